"""End-effector polyhedron P (paper Sec. 5.1 "End-effector integration", Fig. 7 right).

P is a closed or open triangle mesh that roughly encloses the end-effector (a shading element,
a sculptural body). It is given in the end-effector's **body frame** (design units); at the
home configuration (t = inf) it is placed by the reference pose ``S_0`` (world frame), and it
moves rigidly with the end link 3. Two vertices ``L`` and ``R`` of P are joined by bars to
``S_3`` (on ``A_2``) and ``E_3`` (on ``A_3``); unless the user flags them they are the vertices
closest to ``A_2`` and ``A_3`` (MATH §1 point-line distance ``|x × l - m|``). The initial
polyline (eq. 11) routes the end link ``V_2 L R V_3`` (:func:`initial_polyline`).

Meshes load through trimesh (STL, OBJ, GLB, ...). Raw faces are validated, never repaired
silently: non-triangular or out-of-range faces, zero-area faces and non-finite vertices are
refused. Meshes above ``max_faces`` are replaced by their convex hull (an enclosing polyhedron,
so collision checks stay conservative) or, when the hull is still too large, by the oriented
bounding box; with ``simplify=False`` they are refused.
"""

from __future__ import annotations

import stat
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from paraloop_core.algebra import dq
from paraloop_core.errors import EndEffectorError, RealizationError
from paraloop_core.linkage import loops
from paraloop_core.realization.polyline import axis_frames, polyline_length
from paraloop_core.tolerance import TOL

#: Default face limit: the exact edge-face kernels scale with the number of faces and edges.
MAX_FACES = 500


@dataclass(frozen=True)
class Polyhedron:
    """Triangle mesh: ``vertices`` ``(V, 3)`` float64, ``faces`` ``(F, 3)`` int (counter-clockwise
    seen from outside for closed meshes), body frame, design units."""

    vertices: np.ndarray
    faces: np.ndarray

    @property
    def edges(self) -> np.ndarray:
        """Unique undirected edges ``(E, 2)`` (sorted vertex pairs)."""
        return unique_edges(self.faces)

    @property
    def closed(self) -> bool:
        """Every edge is shared by exactly two faces (the mesh bounds a volume)."""
        return is_closed(self.faces)


def unique_edges(faces: np.ndarray) -> np.ndarray:
    """Unique undirected edges ``(E, 2)`` of triangles ``(F, 3)``."""
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    return np.unique(e, axis=0)


def is_closed(faces: np.ndarray) -> bool:
    """True when every undirected edge of ``faces`` ``(F, 3)`` belongs to exactly two faces."""
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return bool(faces.size) and bool(np.all(counts == 2))


def polyhedron(vertices: np.ndarray, faces: np.ndarray, *, max_faces: int = MAX_FACES,
               simplify: bool = True) -> Polyhedron:
    """Validate a raw mesh ``vertices`` ``(V, 3)``, ``faces`` ``(F, 3)`` into a :class:`Polyhedron`.

    Duplicate vertices (e.g. STL's per-face copies) are merged exactly and unused ones dropped.
    Raises :class:`EndEffectorError` with a clear message for malformed input.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 3:
        raise EndEffectorError(f"vertices must be (V >= 3, 3), got {v.shape}", "bad-parameters")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise EndEffectorError(f"faces must be triangles (F, 3), got shape {f.shape}; "
                               "triangulate polygons first", "not-triangles")
    if not np.issubdtype(f.dtype, np.integer):
        raise EndEffectorError("face indices must be integers", "bad-index")
    if f.min() < 0 or f.max() >= len(v):
        raise EndEffectorError(f"face indices must lie in 0..{len(v) - 1}", "bad-index")
    bad = ~np.all(np.isfinite(v), axis=1)
    if np.any(bad):
        raise EndEffectorError(f"{int(bad.sum())} vertices are not finite (first: vertex "
                               f"{int(np.flatnonzero(bad)[0])})", "not-finite")
    uniq, inverse = np.unique(v, axis=0, return_inverse=True)
    f = inverse.reshape(-1)[f]
    used, f = np.unique(f, return_inverse=True)
    v, f = uniq[used], f.reshape(-1, 3)
    degenerate, size = _degenerate(v, f)
    if size <= 0 or np.any(degenerate):
        first = int(np.flatnonzero(degenerate)[0]) if size > 0 else 0
        raise EndEffectorError(f"{int(degenerate.sum()) if size > 0 else len(f)} faces have "
                               f"(near) zero area (first: face {first}); remove them",
                               "degenerate")
    if len(f) > max_faces:
        if not simplify:
            raise EndEffectorError(f"mesh has {len(f)} faces, more than the limit {max_faces}; "
                                   "simplify it or allow the convex hull", "too-large")
        return _enclosing(v, max_faces)
    return Polyhedron(v, f.astype(np.int64))


def _degenerate(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, float]:
    """Faces ``(F,)`` of (near) zero area relative to the mesh's size, and that size."""
    tri = v[f]
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    size = float(np.ptp(v, axis=0).max())
    return area2 <= TOL.residual * size**2, size


def _enclosing(v: np.ndarray, max_faces: int) -> Polyhedron:
    """Convex hull of ``v``, or its oriented bounding box when the hull exceeds ``max_faces``."""
    import trimesh  # heavy import, only needed here

    hull = trimesh.convex.convex_hull(v)
    if len(hull.faces) > max_faces:
        hull = trimesh.PointCloud(v).bounding_box_oriented.to_mesh()
    return polyhedron(hull.vertices, hull.faces, max_faces=max(max_faces, 12), simplify=False)


def load_mesh(path: str | Path, *, max_faces: int = MAX_FACES, simplify: bool = True
              ) -> Polyhedron:
    """Load STL/OBJ/GLB/... with trimesh (all geometry of a scene concatenated) and validate."""
    import trimesh

    path = Path(path)
    try:
        mode = path.stat().st_mode
    except OSError as exc:
        why = "not found" if isinstance(exc, FileNotFoundError) else exc.strerror
        raise EndEffectorError(f"mesh file {why}: {path.name[:80]}", "load", "mesh") from exc
    if not stat.S_ISREG(mode):
        raise EndEffectorError(f"mesh {path.name[:80]} is not a regular file (a directory, "
                               "FIFO or device)", "load", "mesh")
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise EndEffectorError(f"cannot read mesh {path.name[:80]}: {exc}", "load",
                               "mesh") from exc
    faces = getattr(mesh, "faces", None)
    if faces is None or len(faces) == 0:
        raise EndEffectorError(f"mesh {path.name} has no triangle faces", "not-triangles")
    return polyhedron(mesh.vertices, faces, max_faces=max_faces, simplify=simplify)


def disc(radius: float = 1.0, thickness: float = 0.05, segments: int = 24) -> Polyhedron:
    """Closed disc (a thin regular prism) centred at the origin, axis ``+z`` (Fig. 9's disc)."""
    if not (radius > 0 and thickness > 0 and segments >= 3):
        raise EndEffectorError("disc needs radius > 0, thickness > 0, segments >= 3",
                               "bad-parameters")
    a = 2.0 * np.pi * np.arange(segments) / segments
    ring = np.stack([radius * np.cos(a), radius * np.sin(a), np.zeros(segments)], -1)
    h = np.array([0.0, 0.0, thickness / 2.0])
    v = np.concatenate([ring - h, ring + h, [-h, h]])
    i = np.arange(segments)
    j = (i + 1) % segments
    lo, hi = 2 * segments, 2 * segments + 1
    faces = np.concatenate([
        np.stack([i, j, segments + j], 1), np.stack([i, segments + j, segments + i], 1),
        np.stack([np.full(segments, hi), segments + i, segments + j], 1),
        np.stack([np.full(segments, lo), j, i], 1),
    ])
    return Polyhedron(v, faces)


def panel(width: float = 2.0, height: float = 1.0, thickness: float = 0.05) -> Polyhedron:
    """Closed rectangular slab (12 triangles) centred at the origin, normal ``+z``."""
    ext = np.array([width, height, thickness], dtype=np.float64) / 2.0
    if not np.all(ext > 0):
        raise EndEffectorError("panel needs positive width, height and thickness",
                               "bad-parameters")
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * ext
    quads = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4],
                      [1, 5, 7, 3]])
    return Polyhedron(corners, np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]))


def builtin(shape: str, scale: float = 1.0) -> Polyhedron:
    """Built-in shape ``"disc"`` (radius ``scale``) or ``"panel"`` (``2 scale x scale``)."""
    if not (np.isfinite(scale) and scale > 0):
        raise EndEffectorError(f"scale must be positive, got {scale!r}", "bad-parameters",
                               "scale")
    if shape == "disc":
        return disc(scale, 0.05 * scale)
    if shape == "panel":
        return panel(2.0 * scale, scale, 0.05 * scale)
    raise EndEffectorError(f"unknown built-in shape {shape!r} (use 'disc' or 'panel')",
                           "bad-parameters")


def scaled(p: Polyhedron, scale: float) -> Polyhedron:
    """P scaled about its body origin."""
    if not (np.isfinite(scale) and scale > 0):
        raise EndEffectorError(f"scale must be positive, got {scale!r}", "bad-parameters",
                               "scale")
    return Polyhedron(p.vertices * scale, p.faces)


def place(p: Polyhedron, reference: np.ndarray) -> Polyhedron:
    """P at home: body vertices mapped by the reference pose ``S_0`` ``(8,)`` (world frame)."""
    return Polyhedron(dq.transform_points(np.asarray(reference, np.float64), p.vertices), p.faces)


def choose_anchors(home: Polyhedron, axes: np.ndarray, L: int | None = None,
                   R: int | None = None) -> tuple[int, int]:
    """Vertex indices ``(L, R)`` of P at home: the flagged ones, else the vertices closest to
    ``A_2`` and ``A_3`` (``axes`` ``(6, 6)`` unit Plücker lines at home)."""
    n = len(home.vertices)
    for name, idx in (("L", L), ("R", R)):
        if idx is not None and not (isinstance(idx, (int, np.integer)) and 0 <= idx < n):
            raise EndEffectorError(f"{name} must be a vertex index in 0..{n - 1}, got {idx!r}",
                                   "bad-parameters", name)
    lines = np.asarray(axes, np.float64)[[2, 3]]
    dist = np.linalg.norm(np.cross(home.vertices[None], lines[:, None, :3])
                          - lines[:, None, 3:], axis=-1)  # (2, V)
    return (int(np.argmin(dist[0])) if L is None else int(L),
            int(np.argmin(dist[1])) if R is None else int(R))


@dataclass(frozen=True)
class EndEffector:
    """P at home in the base/world frame: ``vertices`` ``(V, 3)``, ``faces`` ``(F, 3)``,
    ``edges`` ``(E, 2)``, anchor vertex indices ``L``, ``R``, ``closed`` (bounds a volume)."""

    vertices: np.ndarray
    faces: np.ndarray
    edges: np.ndarray
    L: int
    R: int
    closed: bool


def attach(body: Polyhedron, reference: np.ndarray, joint_factors: np.ndarray,
           L: int | None = None, R: int | None = None) -> EndEffector:
    """Place P (body frame) by the reference pose ``S_0`` ``(8,)`` and choose L and R: the
    flagged vertex indices, else the vertices closest to ``A_2`` and ``A_3`` of the loop."""
    ref = np.asarray(reference, np.float64)
    if ref.shape != (8,) or not np.all(np.isfinite(ref)) or not np.any(ref[:4]):
        raise EndEffectorError(f"reference must be a finite pose (8,), got shape {ref.shape}",
                               "bad-parameters")
    home = Polyhedron(dq.transform_points(ref, body.vertices), body.faces)
    degenerate, size = _degenerate(home.vertices, home.faces)
    if np.any(degenerate):  # at its place, float64 rounding flattens P's faces
        where = float(np.abs(home.vertices).max())
        raise EndEffectorError(
            f"P of size {float(np.ptp(body.vertices, axis=0).max()):.3g} placed {where:.3g} "
            f"from the origin loses {int(degenerate.sum())} of its faces to float64 rounding: "
            "scale P up or bring the poses nearer the origin (P needs a size of about 1e-8 of "
            "that distance or more)", "degenerate", "scale")
    axes = loops.factor_axes(np.asarray(joint_factors, np.float64))
    left, right = choose_anchors(home, axes, L, R)
    return EndEffector(home.vertices, home.faces, home.edges, left, right, home.closed)


def ee_length(polys: np.ndarray, anchors: np.ndarray, offset: bool = False) -> np.ndarray:
    """Length ``(...)`` of closed polylines ``(..., 6, 3)`` (or 12-vertex offset polylines with
    ``offset``) with the end link routed through L and R (``anchors`` ``(2, 3)``)."""
    a, b = (6, 7) if offset else (2, 3)
    via = np.stack([polys[..., a, :], np.broadcast_to(anchors[0], polys[..., a, :].shape),
                    np.broadcast_to(anchors[1], polys[..., a, :].shape), polys[..., b, :]], -2)
    return polyline_length(polys) - np.linalg.norm(polys[..., a, :] - polys[..., b, :], axis=-1) \
        + np.sum(np.linalg.norm(np.diff(via, axis=-2), axis=-1), axis=-1)


def initial_polyline(joint_factors: np.ndarray, anchors: np.ndarray,
                     fixed: dict[int, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 11 with the end link routed ``V_2 L R V_3``: minimize ``sum |V_i - V_{i+1}|^2``
    over the six-edge cycle with the edge ``V_2 V_3`` replaced by ``|V_2 - L|^2 + |R - V_3|^2``
    (``anchors`` = L, R ``(2, 3)``); ``fixed`` holds ``s_i`` as in
    :func:`polyline.shortest_polyline`. Returns the vertices ``(6, 3)`` and unit axis
    directions ``(6, 3)``."""
    fixed = dict(fixed or {})
    for i, v in fixed.items():
        if not (isinstance(i, (int, np.integer)) and 0 <= i < 6 and np.isfinite(v)):
            raise RealizationError(f"fixed entries must map 0..5 to finite positions, got "
                                   f"{i!r}: {v!r}", "bad-parameters", "fixed")
    q, u = axis_frames(joint_factors)
    # least squares over the seven difference vectors, linear in s (three rows each)
    terms = [(0, 1), (1, 2), (2, 6), (7, 3), (3, 4), (4, 5), (5, 0)]  # 6 = L, 7 = R
    pts_q = np.concatenate([q, anchors])
    pts_u = np.concatenate([u, np.zeros((2, 3))])
    mat = np.zeros((7, 3, 8))
    for r, (a, b) in enumerate(terms):
        mat[r, :, a] += pts_u[a]
        mat[r, :, b] -= pts_u[b]
    rhs = -np.array([pts_q[a] - pts_q[b] for a, b in terms]).reshape(-1)
    mat = mat.reshape(21, 8)[:, :6]
    s = np.zeros(6)
    held = np.array(sorted(fixed), dtype=int)
    s[held] = [float(fixed[i]) for i in held]
    free = np.setdiff1d(np.arange(6), held)
    sub = mat[:, free]
    if np.linalg.cond(sub) > 1.0 / TOL.singular:
        raise RealizationError("the initial polyline is not unique: the free axes are (nearly) "
                               "parallel; fix a vertex on one of them", "singular-loop")
    s[free] = np.linalg.lstsq(sub, rhs - mat[:, held] @ s[held], rcond=None)[0]
    return q + s[:, None] * u, u
