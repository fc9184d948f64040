"""The end link with its end-effector P for fabrication: link 3 = bars ``S_3 L``, ``R E_3`` + P.

Frames and units: home configuration (t = inf), base/world frame; design units unless a name
ends in ``_mm`` or says mm (parts are built in mm with ``scale`` mm per design unit).

P becomes a **solid** (:func:`end_link`):

* a closed P whose mesh is a valid manifold (manifold3d) is used as it is, after making the
  face winding consistent (trimesh) if manifold3d refuses it and turning the faces outward if
  the mesh is inside out: ``method = "closed"``;
* a closed P that manifold3d still refuses (a non-orientable mesh) is replaced by its convex
  hull, which encloses it (``"hull"``, reported);
* an open P (a sheet) is thickened to :data:`SHEET_MM` in total, each triangle swept along its
  normal by half of it on both sides (``"thickened"``; the solid lies within ``SHEET_MM / 2``
  of the surface).

The solid is covered, for carving and verification, by the voxel centres within a margin of it
(:func:`solid_mask`, exact point-triangle distances and winding numbers) and by a chain of
capsules (:func:`parts.principal_capsules`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import manifold3d as m3d
import numpy as np
import trimesh

from paraloop_core.fabrication.profiles import MIN_WALL_MM
from paraloop_core.fabrication.voxelspace import VoxelSpace, point_segment_distance
from paraloop_core.realization.endeffector import EndEffector
from paraloop_core.realization.facecollide import inside_closed, point_triangle_distance

if TYPE_CHECKING:
    from paraloop_core.realization.ee_certificate import EndEffectorRealization

SHEET_MM = MIN_WALL_MM  # total printed thickness of an open (sheet) end-effector
_CHUNK = 1024  # points per distance batch (memory only)


@dataclass(frozen=True)
class EndLink:
    """Link 3 with P: ``bars`` ``(2, 2, 3)`` = ``S_3 L``, ``R E_3``; P's surface ``vertices``
    ``(V, 3)``, ``faces`` ``(F, 3)`` (outward for a solid); ``sheet``: open, thickened by
    :data:`SHEET_MM`; ``method``: ``"closed"``, ``"hull"`` or ``"thickened"``."""

    bars: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    sheet: bool
    method: str


def _mesh(vertices: np.ndarray, faces: np.ndarray) -> m3d.Manifold:
    return m3d.Manifold(m3d.Mesh(np.ascontiguousarray(vertices, np.float32),
                                 np.ascontiguousarray(faces, np.uint32)))


def end_link(effector: EndEffector | EndEffectorRealization, points: np.ndarray) -> EndLink:
    """The end link of a realization with an end-effector: ``effector`` is an
    :class:`endeffector.EndEffector` or a ``ee_certificate.EndEffectorRealization`` (its
    ``effector``), ``points`` ``(12, 3)`` the offset polyline (``S_3 = points[6]``,
    ``E_3 = points[7]``)."""
    ee = getattr(effector, "effector", effector)
    pts = np.asarray(points, float)
    v, f = np.asarray(ee.vertices, float), np.asarray(ee.faces, np.int64)
    bars = np.array([[pts[6], v[ee.L]], [v[ee.R], pts[7]]])
    if not ee.closed:
        return EndLink(bars, v, f, True, "thickened")
    if _mesh(v, f).status() != m3d.Error.NoError:  # e.g. a face turned the wrong way
        mesh = trimesh.Trimesh(v, f, process=False)
        trimesh.repair.fix_winding(mesh)
        f = np.asarray(mesh.faces, np.int64)
    tri = v[f]
    if np.sum(tri[:, 0] * np.cross(tri[:, 1], tri[:, 2])) < 0:  # 6 x signed volume
        f = f[:, ::-1]
    if _mesh(v, f).status() == m3d.Error.NoError:
        return EndLink(bars, v, f, False, "closed")
    hull = m3d.Manifold.hull_points(np.ascontiguousarray(v, np.float32)).to_mesh()
    return EndLink(bars, np.asarray(hull.vert_properties[:, :3], float),
                   np.asarray(hull.tri_verts, np.int64), False, "hull")


def solid_manifold(el: EndLink, scale: float) -> m3d.Manifold:
    """P's solid in mm (home frame)."""
    v = el.vertices * scale
    if not el.sheet:
        return _mesh(v, el.faces)
    tri = v[el.faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    off = 0.5 * SHEET_MM * n / np.linalg.norm(n, axis=1, keepdims=True)
    prisms = [m3d.Manifold.hull_points(np.concatenate([t + o, t - o]).astype(np.float32))
              for t, o in zip(tri, off, strict=True)]
    return m3d.Manifold.batch_boolean(prisms, m3d.OpType.Add)


def solid_mask(el: EndLink, x: np.ndarray, margin: float, scale: float) -> np.ndarray:
    """Mask ``(N,)``: points ``(N, 3)`` within ``margin`` of P's solid (design units; a sheet's
    solid lies within ``SHEET_MM / 2 / scale`` of its surface)."""
    tri = el.vertices[el.faces]
    reach = margin + (0.5 * SHEET_MM / scale if el.sheet else 0.0)
    out = np.zeros(len(x), bool)
    for s in range(0, len(x), _CHUNK):
        p = x[s:s + _CHUNK]
        near = point_triangle_distance(p[:, None], tri[None]).min(axis=1) <= reach
        out[s:s + _CHUNK] = near if el.sheet else near | inside_closed(el.vertices, el.faces, p)
    return out


def _grid(lo: np.ndarray, hi: np.ndarray, pitch: float) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned grid frame ``(4, 4)`` from ``lo`` and its centres ``(X, Y, Z, 3)`` covering
    ``hi``."""
    dims = np.ceil((hi - lo) / pitch).astype(int) + 1
    frame = np.eye(4)
    frame[:3, 3] = lo
    idx = np.stack(np.meshgrid(*[np.arange(d) for d in dims], indexing="ij"), -1)
    return frame, lo + idx * pitch


def _mask_in(el: EndLink, centers: np.ndarray, margin: float, scale: float) -> np.ndarray:
    """:func:`solid_mask` on a grid of centres ``(..., 3)``, evaluated only near P's box."""
    lo, hi = el.vertices.min(0) - 2 * margin - SHEET_MM / scale, \
        el.vertices.max(0) + 2 * margin + SHEET_MM / scale
    near = np.all((centers >= lo) & (centers <= hi), axis=-1)
    out = np.zeros(centers.shape[:-1], bool)
    out[near] = solid_mask(el, centers[near], margin, scale)
    return out


def solid_space(el: EndLink, pitch: float, scale: float) -> VoxelSpace:
    """P's solid as a voxel space of ``pitch`` whose region (balls of the half-diagonal ``h``
    about the occupied centres) contains it: every centre within ``h`` of the solid."""
    h = np.sqrt(3.0) / 2.0 * pitch
    pad = h + pitch + (SHEET_MM / scale if el.sheet else 0.0)
    frame, centers = _grid(el.vertices.min(0) - pad, el.vertices.max(0) + pad, pitch)
    return VoxelSpace(solid_mask(el, centers.reshape(-1, 3), h, scale).reshape(
        centers.shape[:-1]), pitch, frame)


def link_space(el: EndLink, radius: float, scale: float, resolution: int = 128) -> VoxelSpace:
    """Potential design space of link 3: capsules of ``radius`` about both bars plus P's solid
    (covered as in :func:`solid_space`), on an axis-aligned grid with ``resolution`` voxels
    along its longest side."""
    pts = np.concatenate([el.bars.reshape(-1, 3), el.vertices])
    lo, hi = pts.min(0) - radius, pts.max(0) + radius
    pitch = float(np.max(hi - lo)) / resolution
    frame, centers = _grid(lo, hi, pitch)
    occ = np.min([point_segment_distance(centers, p0, p1) for p0, p1 in el.bars], 0) <= radius
    return VoxelSpace(occ | _mask_in(el, centers, np.sqrt(3.0) / 2.0 * pitch, scale), pitch,
                      frame)
