"""Framing the camera, in the part of the view left of the GUI panel.

viser's camera: ``position`` and ``look_at`` in world coordinates (z up), ``fov`` the vertical
field of view in radians; the control panel ("medium" width, 20 em) floats over the right of
the canvas, so the scene is centred in what is left of it.

Two framings (issue 28: the designer sees the object they will build). Opening a design and
its printed parts arriving frame the *object*: the linkage as drawn (printed parts or solid
links) and the free targets (the gizmos one drags), from the direction, among
:func:`directions`, in which the object covers the most of the view (:func:`best_view`).
*Frame all* keeps each browser's direction and frames everything (:func:`framing`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import viser
from scipy.spatial import ConvexHull, QhullError

from app.labels import View

#: Canvas pixels hidden by the control panel on the right (20 em of 16 px, plus its margin).
PANEL_PX = 340.0
#: Canvas assumed before a browser reports its size (the Playwright / laptop default).
DEFAULT_SIZE = (1280.0, 800.0)
#: Default viewing direction (from the scene towards the camera): *Frame all* without one.
DEFAULT_DIRECTION = np.array([0.8, -1.1, 0.7])
#: Share of the free region's width and height kept free at each side of the object, and of
#: a target's centre (its gizmo and label reach beyond it).
MARGIN = 0.06
TARGET_MARGIN = 0.04
#: Least distance (along the view) from the camera to the nearest point, as a share of the
#: points' largest extent: a camera closer than that would blow its nearest piece up.
NEAREST = 0.35
#: Elevations (deg) and azimuth step (deg) of the directions the object is viewed from.
ELEVATIONS = (10.0, 20.0, 30.0, 45.0)
AZIMUTH_STEP = 15.0
#: Triangles of the object scored per direction (a sample of a larger mesh).
SCORED_TRIANGLES = 4000


@dataclasses.dataclass(frozen=True)
class Subject:
    """What a framing shows: ``points`` ``(N, 3)`` kept in view with ``margins`` ``(N,)``
    (share of the free region per side) and the object's ``triangles`` ``(M, 3, 3)``, whose
    area on screen picks the viewing direction."""

    points: np.ndarray
    margins: np.ndarray
    triangles: np.ndarray


def subject(triangles: np.ndarray, targets: np.ndarray, extra: np.ndarray | None = None
            ) -> Subject:
    """The object of ``triangles`` with ``targets`` ``(K, 3)`` (and ``extra`` points, same
    margin as the object) in view; the object's points reduced to their convex hull."""
    tris = np.asarray(triangles, float).reshape(-1, 3, 3)
    tris = tris[np.all(np.isfinite(tris), axis=(1, 2))]
    pts = tris.reshape(-1, 3)
    if extra is not None:
        pts = np.vstack([pts, np.asarray(extra, float).reshape(-1, 3)])
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) > 64:
        try:
            pts = pts[ConvexHull(pts).vertices]
        except QhullError:  # flat or degenerate: every point
            pass
    tg = np.asarray(targets, float).reshape(-1, 3)
    tg = tg[np.all(np.isfinite(tg), axis=1)]
    if len(pts) + len(tg) == 0:
        tg = np.zeros((1, 3))
    return Subject(np.vstack([pts, tg]),
                   np.r_[np.full(len(pts), MARGIN), np.full(len(tg), TARGET_MARGIN)], tris)


def _basis(direction: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(right, up, forward) of a z-up camera looking along ``-direction``."""
    fwd = -np.asarray(direction, float) / np.linalg.norm(direction)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    if np.linalg.norm(right) < 1e-6:  # looking straight down: any horizontal right
        right = np.array([1.0, 0.0, 0.0])
    right /= np.linalg.norm(right)
    return right, np.cross(right, fwd), fwd


def framing(shot: Subject, fov: float, size: tuple[float, float],
            direction: np.ndarray = DEFAULT_DIRECTION, panel_px: float = PANEL_PX
            ) -> tuple[np.ndarray, np.ndarray]:
    """Camera ``(position, look_at)`` as close as it gets while every point of ``shot`` stays
    in the canvas of ``size`` (width, height) px left of a panel ``panel_px`` wide, inside
    its margin, looking along ``-direction`` (z up) with vertical field of view ``fov``
    (rad), no nearer to them than :data:`NEAREST`. The distance is found by bisection; the
    sideways position then centres the points' room; ``look_at`` is on the view axis at
    the points' middle depth."""
    width, height = (float(s) if s and s > 0 else d
                     for s, d in zip(size, DEFAULT_SIZE, strict=True))
    right, up, fwd = _basis(direction)
    f = 0.5 * height / np.tan(0.5 * fov)
    free = max(width - panel_px, 0.35 * width)
    m = np.asarray(shot.margins, float)
    left, right_edge = (m * free - 0.5 * width) / f, ((1.0 - m) * free - 0.5 * width) / f
    top = (0.5 - m) * height / f  # the slopes x / z, y / z of the free region's edges
    x, y, z = shot.points @ right, shot.points @ up, shot.points @ fwd

    def room(cz: float) -> tuple[bool, float, float]:
        lo_x, hi_x = np.max(x - right_edge * (z - cz)), np.min(x - left * (z - cz))
        lo_y, hi_y = np.max(y - top * (z - cz)), np.min(y + top * (z - cz))
        return lo_x <= hi_x and lo_y <= hi_y, 0.5 * (lo_x + hi_x), 0.5 * (lo_y + hi_y)

    span = max(float(np.ptp(shot.points, axis=0).max()), 1e-9)
    near, far = float(z.min()) - NEAREST * span, float(z.min()) - 1e3 * span
    for _ in range(36):
        mid = 0.5 * (near + far)
        if room(mid)[0]:
            far = mid
        else:
            near = mid
    _, cx, cy = room(far)
    position = cx * right + cy * up + far * fwd
    return position, position + (0.5 * (z.min() + z.max()) - far) * fwd


def directions() -> np.ndarray:
    """Candidate viewing directions ``(K, 3)`` (towards the camera): every
    :data:`AZIMUTH_STEP` degrees at each of the :data:`ELEVATIONS` above the horizon."""
    el = np.radians(np.asarray(ELEVATIONS))[:, None]
    az = np.radians(np.arange(0.0, 360.0, AZIMUTH_STEP))[None, :]
    return np.stack(np.broadcast_arrays(np.cos(el) * np.cos(az), np.cos(el) * np.sin(az),
                                        np.sin(el)), axis=-1).reshape(-1, 3)


def screen_area(view: View, triangles: np.ndarray) -> float:
    """Half the summed on-screen area (px) of ``triangles``: a closed surface's outline
    area, overlaps counted again."""
    px, _ = view.project(triangles.reshape(-1, 3))
    p = px.reshape(-1, 3, 2)
    a, b = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    return 0.25 * float(np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]).sum())


def best_view(shot: Subject, fov: float, size: tuple[float, float] = DEFAULT_SIZE) -> View:
    """The :func:`framing` of ``shot`` from the candidate direction in which its object's
    triangles cover the most of the screen (the default direction without triangles)."""
    tris = shot.triangles[::max(1, len(shot.triangles) // SCORED_TRIANGLES)]
    best: tuple[float, View] | None = None
    for d in directions() if len(tris) else [DEFAULT_DIRECTION]:
        view = View(*framing(shot, fov, size, d), fov, size)
        score = screen_area(view, tris) if len(tris) else 0.0
        if best is None or score > best[0]:
            best = (score, view)
    assert best is not None
    return best[1]


def _aim(cam: Any, position: np.ndarray, look_at: np.ndarray) -> None:
    """Point a camera (the initial one or a browser's), clipping planes by the distance."""
    dist = float(np.linalg.norm(position - look_at))
    cam.near, cam.far = 1e-3 * dist, 1e3 * dist
    cam.position = position  # viser keeps the orientation: look_at must come after
    cam.look_at = look_at


def _reported(cam: Any) -> bool:
    """Whether a browser has reported its camera (else it starts from the initial one)."""
    try:
        cam.update_timestamp  # noqa: B018 - asserts that the browser reported its camera
    except AssertionError:
        return False
    return True


def frame_object(server: viser.ViserServer, shot: Subject, clients: list[Any] | None = None
                 ) -> tuple[View, dict[int, np.ndarray]]:
    """Frame ``shot`` from its :func:`best_view` for new clients (initial camera) and the
    browsers ``clients`` (default: every connected one). Returns that view (the labels are
    placed for it) and the camera position set per client id."""
    cam0 = server.initial_camera
    view = best_view(shot, float(cam0.fov))
    _aim(cam0, view.position, view.look_at)
    aimed = {}
    for client in server.get_clients().values() if clients is None else clients:
        cam: Any = client.camera
        if not _reported(cam):
            continue
        size = (float(cam.image_width), float(cam.image_height))
        fov = cam.fov if cam.fov and cam.fov > 0 else cam0.fov
        position, look_at = framing(shot, fov, size, view.position - view.look_at)
        with client.atomic():
            _orbit(cam, float(np.linalg.norm(position - look_at)))
            _aim(cam, position, look_at)
        aimed[client.client_id] = position
    return view, aimed


def unmoved(cam: Any, position: np.ndarray) -> bool:
    """Whether a browser's camera is still at ``position`` (within a thousandth of its
    distance to the look-at point: the browser's report rounds; one that has not reported
    yet starts from the initial camera)."""
    if not _reported(cam):
        return True
    here = np.asarray(cam.position, float)
    dist = float(np.linalg.norm(here - np.asarray(cam.look_at, float)))
    return bool(np.linalg.norm(here - position) <= 1e-3 * max(dist, 1e-12))


def _orbit(cam: Any, dist: float) -> None:
    """The orbit range of a browser's camera for a framing at ``dist``."""
    cam.max_orbit_distance = max(1e4, 100.0 * dist)
    cam.min_orbit_distance = min(0.01, 1e-3 * dist)


def frame_all(server: viser.ViserServer, shot: Subject) -> View | None:
    """*Frame all*: every browser keeps its viewing direction and frames ``shot``. Returns
    the first framed browser's view (the labels are placed for it; None: no browser)."""
    view = None
    for client in server.get_clients().values():
        cam: Any = client.camera
        if not _reported(cam):
            continue
        away = np.asarray(cam.position, float) - np.asarray(cam.look_at, float)
        if not (np.linalg.norm(away) > 0 and np.all(np.isfinite(away))):
            away = DEFAULT_DIRECTION
        fov = cam.fov if cam.fov and cam.fov > 0 else server.initial_camera.fov
        size = (float(cam.image_width), float(cam.image_height))
        position, look_at = framing(shot, fov, size, away)
        if view is None and min(size) > 0:
            view = View(position, look_at, float(fov), size)
        with client.atomic():
            _orbit(cam, float(np.linalg.norm(position - look_at)))
            _aim(cam, position, look_at)
    return view
