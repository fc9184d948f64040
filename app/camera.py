"""Framing the camera on the whole scene, in the part of the view left of the GUI panel.

viser's camera: ``position`` and ``look_at`` in world coordinates (z up), ``fov`` the vertical
field of view in radians; the control panel ("medium" width, 20 em) floats over the right of
the canvas, so the scene is centred in what is left of it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import viser

from app.labels import View

#: Canvas pixels hidden by the control panel on the right (20 em of 16 px, plus its margin).
PANEL_PX = 340.0
#: Canvas assumed before a browser reports its size (the Playwright / laptop default).
DEFAULT_SIZE = (1280.0, 800.0)
#: Default viewing direction (from the scene towards the camera) when opening a design.
DEFAULT_DIRECTION = np.array([0.8, -1.1, 0.7])
#: Fraction of the free view the scene's bounding sphere may fill.
FILL = 0.85


def framing(points: np.ndarray, fov: float, size: tuple[float, float],
            direction: np.ndarray = DEFAULT_DIRECTION, panel_px: float = PANEL_PX
            ) -> tuple[np.ndarray, np.ndarray]:
    """Camera ``(position, look_at)`` showing every point of ``points`` ``(N, 3)`` in the
    canvas of ``size`` (width, height) px left of a panel ``panel_px`` wide, looking along
    ``-direction`` (z up) with vertical field of view ``fov`` (rad).

    The bounding sphere of the points (centre of the box, farthest point) fits in the free
    region's half-angle with margin :data:`FILL`; the look-at point moves right so that the
    sphere's centre lands in the middle of the free region."""
    pts = np.asarray(points, float).reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) == 0:
        pts = np.zeros((1, 3))
    center = 0.5 * (pts.min(0) + pts.max(0))
    radius = max(float(np.linalg.norm(pts - center, axis=1).max()), 1e-9)
    width, height = (float(s) if s and s > 0 else d
                     for s, d in zip(size, DEFAULT_SIZE, strict=True))
    free = max(width - panel_px, 0.35 * width) / width  # share of the width left of the panel
    tan_v = np.tan(0.5 * fov)
    tan_h = tan_v * width / height
    half = np.arctan(min(tan_v, tan_h * free))  # half-angle of the free region
    dist = radius / (FILL * np.sin(half))
    d = np.asarray(direction, float)
    d = d / np.linalg.norm(d)
    right = np.cross(-d, [0.0, 0.0, 1.0])
    if np.linalg.norm(right) < 1e-6:  # looking straight down: any horizontal right
        right = np.array([1.0, 0.0, 0.0])
    right /= np.linalg.norm(right)
    # the free region's middle is (1 - free) of the half-width left of the canvas centre
    look_at = center + (1.0 - free) * dist * tan_h * right
    return look_at + dist * d, look_at


def frame_all(server: viser.ViserServer, points: np.ndarray, keep_direction: bool = False
              ) -> View:
    """Frame ``points`` for new clients (initial camera) and every connected browser; with
    ``keep_direction`` each browser keeps its viewing direction (the *Frame all* button).
    Clipping planes and the orbit range follow the distance, so a design in any unit shows.
    Returns the view the labels are placed for: the initial camera's, or with
    ``keep_direction`` the first framed browser's."""
    pts = np.asarray(points, float)
    cam0 = server.initial_camera
    position, look_at = framing(pts, cam0.fov, DEFAULT_SIZE)
    dist = float(np.linalg.norm(position - look_at))
    cam0.near, cam0.far = 1e-3 * dist, 1e3 * dist
    cam0.position, cam0.look_at = position, look_at
    view = View(position, look_at, float(cam0.fov), DEFAULT_SIZE)
    for client in server.get_clients().values():
        cam: Any = client.camera
        try:
            cam.update_timestamp  # noqa: B018 - asserts that the browser reported its camera
        except AssertionError:
            continue  # not reported yet: it starts from the initial camera
        direction = DEFAULT_DIRECTION
        if keep_direction:
            away = np.asarray(cam.position, float) - np.asarray(cam.look_at, float)
            if np.linalg.norm(away) > 0 and np.all(np.isfinite(away)):
                direction = away
        fov = cam.fov if cam.fov and cam.fov > 0 else cam0.fov
        size = (float(cam.image_width), float(cam.image_height))
        position, look_at = framing(pts, fov, size, direction)
        if keep_direction and view.size is DEFAULT_SIZE and min(size) > 0:
            view = View(position, look_at, float(fov), size)
        dist = float(np.linalg.norm(position - look_at))
        with client.atomic():
            cam.max_orbit_distance = max(1e4, 100.0 * dist)
            cam.min_orbit_distance = min(0.01, 1e-3 * dist)
            cam.near, cam.far = 1e-3 * dist, 1e3 * dist
            cam.position = position  # viser keeps the orientation: look_at must come after
            cam.look_at = look_at
    return view
