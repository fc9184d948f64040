"""Voxel link design spaces: the home-frame voxel grid, its region, and the potential design
spaces (capsules about the bars, user meshes) that :mod:`carve` carves.

Frames and units: every link's geometry lives in its **home frame** (the base frame at
``t = inf``, where all link poses are the identity), in design units. A voxel space stores its
centres as ``frame @ [pitch * (i, j, k), 1]``; its *region* is the union of closed balls of
radius ``h = sqrt(3)/2 pitch`` (the voxel half-diagonal) about the occupied centres. That region
contains every voxel cube and the meshes of :mod:`meshing`, and all guarantees of :mod:`carve`
are about it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from paraloop_core.errors import FabricationError


@dataclass(frozen=True)
class VoxelSpace:
    """Occupancy ``(nx, ny, nz)`` bool; voxel ``(i,j,k)`` has its centre at
    ``frame @ [pitch*(i,j,k), 1]`` in the link's home frame (design units)."""

    occupancy: np.ndarray
    pitch: float
    frame: np.ndarray

    @property
    def half_diagonal(self) -> float:
        return float(np.sqrt(3.0) / 2.0 * self.pitch)

    def centers(self, mask: np.ndarray | None = None) -> np.ndarray:
        """Home-frame centres ``(N, 3)`` of the voxels in ``mask`` (default: occupied)."""
        idx = np.argwhere(self.occupancy if mask is None else mask) * self.pitch
        return idx @ self.frame[:3, :3].T + self.frame[:3, 3]

    def with_occupancy(self, occ: np.ndarray) -> VoxelSpace:
        return VoxelSpace(occ, self.pitch, self.frame)

    def coarsened(self, stride: int) -> VoxelSpace:
        """Blocks of ``stride`` voxels per axis, occupied where any voxel is: a coarse voxel's
        ball (radius ``stride`` times this half-diagonal) contains the balls of its voxels
        (their centres lie within ``(stride - 1) h`` of its centre), so the region only grows."""
        if stride == 1:
            return self
        n = -(-np.array(self.occupancy.shape) // stride)  # ceil
        occ = np.zeros(n * stride, bool)
        occ[tuple(slice(0, k) for k in self.occupancy.shape)] = self.occupancy
        occ = occ.reshape(n[0], stride, n[1], stride, n[2], stride).any(axis=(1, 3, 5))
        frame = self.frame.copy()  # origin at the centre of block (0, 0, 0)
        frame[:3, 3] += frame[:3, :3] @ np.full(3, 0.5 * (stride - 1) * self.pitch)
        return VoxelSpace(occ, self.pitch * stride, frame)


def _bar_frame(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Rotation ``(3, 3)`` with first column along ``p1 - p0`` (any, if degenerate)."""
    e = p1 - p0
    e = e / n if (n := np.linalg.norm(e)) > 0 else np.array([1.0, 0, 0])
    f = np.cross(e, [1.0, 0, 0] if abs(e[0]) < 0.9 else [0, 1.0, 0])
    f /= np.linalg.norm(f)
    return np.stack([e, f, np.cross(e, f)], axis=1)


def point_segment_distance(x: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Distance ``(...)`` of points ``(..., 3)`` to the segment ``[p0, p1]``."""
    d = p1 - p0
    t = np.clip((x - p0) @ d / max(float(d @ d), 1e-300), 0.0, 1.0)
    return np.linalg.norm(x - p0 - t[..., None] * d, axis=-1)


def capsule_space(p0: np.ndarray, p1: np.ndarray, radius: float,
                  resolution: int = 128) -> VoxelSpace:
    """Cylinder of ``radius`` about the bar ``[p0, p1]`` with hemispherical ends (the default
    potential design space), on a bar-aligned grid with ``resolution`` voxels along its longest
    side."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    if not (radius > 0 and np.isfinite(radius)) or resolution < 8:
        raise FabricationError("design-space radius must be > 0 and resolution >= 8",
                               "bad-parameters")
    length = float(np.linalg.norm(p1 - p0))
    pitch = (length + 2 * radius) / resolution
    rot = _bar_frame(p0, p1)
    dims = np.ceil(np.array([length + 2 * radius, 2 * radius, 2 * radius]) / pitch).astype(int) + 1
    frame = np.eye(4)
    frame[:3, :3] = rot
    frame[:3, 3] = p0 - rot @ np.full(3, radius)
    grid = np.stack(np.meshgrid(*[np.arange(d) for d in dims], indexing="ij"), -1) * pitch
    home = grid @ rot.T + frame[:3, 3]
    occ = point_segment_distance(home, p0, p1) <= radius
    return VoxelSpace(occ, pitch, frame)


def mesh_space(vertices: np.ndarray, faces: np.ndarray, pitch: float) -> VoxelSpace:
    """A user mesh (home frame of its link, design units) as a filled voxel space."""
    import trimesh

    mesh = trimesh.Trimesh(np.asarray(vertices, float), np.asarray(faces), process=True)
    if not mesh.is_watertight or not pitch > 0:
        raise FabricationError("a user design space must be a watertight mesh and pitch > 0",
                               "bad-parameters")
    vox = mesh.voxelized(pitch).fill()
    frame = np.asarray(vox.transform, float) @ np.diag([1 / pitch] * 3 + [1.0])
    return VoxelSpace(np.asarray(vox.matrix, bool), pitch, frame)


def default_spaces(points: np.ndarray, radius: float | Sequence[float],
                   base_radius: float | None = None, resolution: int = 128) -> list[VoxelSpace]:
    """Capsules about the six bars (``points`` ``(12, 3)``, design units) of ``radius`` (one
    value, or six, e.g. a realization's design-space radii); with one value the base link's
    gets ``base_radius`` (default ``2 radius``: large, for grounding)."""
    pts = check_points(points)
    radii = space_radii(radius, base_radius)
    return [capsule_space(pts[2 * i], pts[2 * i + 1], radii[i], resolution) for i in range(6)]


def space_radii(radius: float | Sequence[float], base_radius: float | None = None
                ) -> list[float]:
    """The six capsule radii of :func:`default_spaces`: ``radius`` given six times, or one
    value for links 1-5 and ``base_radius`` (default ``2 radius``) for the base link."""
    if np.ndim(radius) == 0:
        return [float(base_radius if base_radius is not None else 2.0 * radius)] + \
            [float(radius)] * 5
    radii = [float(r) for r in radius]
    if len(radii) != 6:
        raise FabricationError("give one design-space radius or six", "bad-parameters")
    return radii


#: Voxels per capsule radius that the automatic resolution aims for, over the thinnest
#: space: with fewer, nothing is deep enough to mesh once the motion margin (which shrinks
#: with the pitch) is taken off (tv8 at 96 voxels: 4 of 6 spaces; arc-sculpture at 128: 2).
AUTO_VOXELS_PER_RADIUS = 4.5
#: Resolutions the automatic choice picks from (cost grows with the cube). At least 128, the
#: long-standing CLI default: at 96 sun-disc's carved parts (radius 0.2) were not watertight.
AUTO_RESOLUTIONS = (128, 160, 192, 224, 256)


def auto_resolution(points: np.ndarray, radius: float | Sequence[float],
                    base_radius: float | None = None) -> int:
    """Voxels along a design space for :func:`default_spaces` (same arguments): the smallest
    of :data:`AUTO_RESOLUTIONS` that puts :data:`AUTO_VOXELS_PER_RADIUS` voxels across every
    capsule's radius (the largest when none does)."""
    pts = check_points(points).reshape(6, 2, 3)
    radii = np.array(space_radii(radius, base_radius))
    if not np.all(np.isfinite(radii) & (radii > 0)):
        raise FabricationError("design-space radii must be positive and finite",
                               "bad-parameters")
    extent = np.linalg.norm(pts[:, 1] - pts[:, 0], axis=1) + 2.0 * radii
    need = float(np.max(AUTO_VOXELS_PER_RADIUS * extent / radii))
    return next((r for r in AUTO_RESOLUTIONS if r >= need), AUTO_RESOLUTIONS[-1])


def check_points(points: np.ndarray) -> np.ndarray:
    """The offset polyline ``points`` as a float ``(12, 3)`` array; raises if not finite."""
    pts = np.asarray(points, float)
    if pts.shape != (12, 3) or not np.all(np.isfinite(pts)):
        raise FabricationError(f"points must be a finite (12, 3) polyline, got {pts.shape}",
                               "bad-parameters")
    return pts
