"""Target labels placed on screen so that no two overlap in the framing camera's view.

viser draws a label (``add_label``, screen-sized font) as a text box of constant pixel size at
a 3D anchor; two anchors that are far apart in space can still put their boxes on top of each
other on screen (one behind the other). So labels are placed in the image of a :class:`View`
(the camera that framed the design): each box goes next to its target, on the first free spot
found walking outwards from the targets' centre, and is anchored back in 3D at its target's
depth. Other views may still overlap them (one set of scene labels serves every camera).

Pixel coordinates: x right, y down, origin at the canvas' top-left corner.
"""

from __future__ import annotations

import dataclasses

import numpy as np

#: Generous size of viser's label box at font scale 1 (12 CSS px em, system sans-serif, a
#: 0.2-line padding): width per character and height, px; and the gap kept between boxes.
CHAR_PX = 8.0
LINE_PX = 22.0
GAP_PX = 3.0
#: Half-size (px) of the square kept free around every target's centre (its gizmo's handle).
TARGET_PX = 8.0
#: Candidate spots: directions per ring and rings (one label box height apart).
DIRECTIONS = 24
RINGS = 40


@dataclasses.dataclass(frozen=True)
class View:
    """A z-up pinhole camera: ``position`` and ``look_at`` (world), vertical ``fov`` (rad) and
    the canvas ``size`` (width, height) in px."""

    position: np.ndarray
    look_at: np.ndarray
    fov: float
    size: tuple[float, float]

    def _basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        fwd = np.asarray(self.look_at, float) - np.asarray(self.position, float)
        fwd = fwd / np.linalg.norm(fwd)
        right = np.cross(fwd, [0.0, 0.0, 1.0])
        if np.linalg.norm(right) < 1e-9:  # looking straight up or down
            right = np.array([1.0, 0.0, 0.0])
        right = right / np.linalg.norm(right)
        return right, np.cross(right, fwd), fwd, 0.5 * self.size[1] / np.tan(0.5 * self.fov)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixels ``(N, 2)`` and depths ``(N,)`` (along the view direction) of world points
        ``(N, 3)``; points at or behind the camera get depth <= 0 (their pixels are
        meaningless)."""
        right, up, fwd, f = self._basis()
        rel = np.asarray(points, float).reshape(-1, 3) - np.asarray(self.position, float)
        z = rel @ fwd
        zs = np.where(z > 0, z, 1.0)
        px = np.stack([0.5 * self.size[0] + f * (rel @ right) / zs,
                       0.5 * self.size[1] - f * (rel @ up) / zs], axis=-1)
        return px, z

    def unproject(self, px: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """World points ``(N, 3)`` seen at pixels ``px`` ``(N, 2)`` at ``depth`` ``(N,)``."""
        right, up, fwd, f = self._basis()
        px = np.asarray(px, float).reshape(-1, 2)
        z = np.asarray(depth, float).reshape(-1, 1)
        x = (px[:, :1] - 0.5 * self.size[0]) / f
        y = (0.5 * self.size[1] - px[:, 1:]) / f
        return np.asarray(self.position, float) + z * (fwd + x * right + y * up)


def box_sizes(texts: list[str]) -> np.ndarray:
    """Estimated label box sizes ``(N, 2)`` (width, height) px of ``texts``."""
    n = np.array([max(len(t), 1) for t in texts], float)
    return np.stack([CHAR_PX * n + 0.4 * LINE_PX, np.full(len(texts), LINE_PX)], axis=-1)


def boxes(view: View, anchors: np.ndarray, texts: list[str]) -> np.ndarray:
    """Screen boxes ``(N, 4)`` (x0, y0, x1, y1) px of labels centred at world ``anchors``."""
    px, _ = view.project(anchors)
    half = 0.5 * box_sizes(texts)
    return np.concatenate([px - half, px + half], axis=-1)


def overlaps(a: np.ndarray, b: np.ndarray, gap: float = 0.0) -> np.ndarray:
    """Whether boxes ``a`` ``(N, 4)`` and ``b`` ``(M, 4)`` come closer than ``gap`` px:
    ``(N, M)``."""
    a, b = a[:, None], b[None]
    return ((a[..., 0] < b[..., 2] + gap) & (b[..., 0] < a[..., 2] + gap)
            & (a[..., 1] < b[..., 3] + gap) & (b[..., 1] < a[..., 3] + gap))


def place(targets: np.ndarray, texts: list[str], view: View) -> np.ndarray:
    """World anchors ``(N, 3)`` (box centres, anchor ``center-center``) of the labels
    ``texts`` of ``targets`` ``(N, 3)``: seen from ``view``, no two boxes overlap (kept
    :data:`GAP_PX` apart) and no box covers a target's centre. Greedy, in target order:
    the first free spot on rings around the target, directions closest to "away from the
    targets' centre" first. Targets at or behind the camera keep their own position."""
    targets = np.asarray(targets, float).reshape(-1, 3)
    px, depth = view.project(targets)
    sizes = box_sizes(texts)
    visible = depth > 0
    centre = px[visible].mean(0) if visible.any() else np.zeros(2)
    avoid = np.concatenate([px[visible] - TARGET_PX, px[visible] + TARGET_PX], axis=-1)
    placed = np.zeros((0, 4))
    out = targets.copy()
    angles = 2 * np.pi * np.arange(DIRECTIONS) / DIRECTIONS
    rings = np.arange(RINGS)
    for i in np.flatnonzero(visible):
        w, h = sizes[i]
        away = px[i] - centre
        heading = np.arctan2(away[1], away[0]) if np.linalg.norm(away) > 1.0 else -0.5 * np.pi
        # nearest ring first, then the direction closest to the heading
        turn = np.abs((angles - heading + np.pi) % (2 * np.pi) - np.pi)
        order = np.argsort(turn, kind="stable")
        radius = TARGET_PX + 0.5 * np.hypot(w, h) + GAP_PX + h * rings  # (R,)
        ang = angles[order]
        spots = px[i] + radius[:, None, None] * np.stack([np.cos(ang), np.sin(ang)], -1)
        spots = spots.reshape(-1, 2)
        cand = np.concatenate([spots - [w / 2, h / 2], spots + [w / 2, h / 2]], axis=-1)
        blocked = overlaps(cand, np.vstack([placed, avoid]), GAP_PX).any(axis=1)
        k = int(np.argmin(blocked))  # the first free spot (all blocked: the nearest)
        placed = np.vstack([placed, cand[k]])
        out[i] = view.unproject(spots[k][None], depth[i:i + 1])[0]
    return out
