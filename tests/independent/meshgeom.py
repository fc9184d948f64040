"""Mesh measurements for the printed-part checker, written independently of ``paraloop_core``.

Only numpy and scipy: parallel plane sections of a triangle mesh (each section point labelled
by the mesh edge it lies on, so loops are the connected components), 2D rays cast from a point
of a section, the least caliper width of a convex hull, the area of a triangle above a level.
All lengths are in the mesh's unit (mm for the export's files).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull

#: Resolution of a length read from the files (mm): STL and 3MF vertices are float32, ~2e-5 mm
#: at 300 mm. A figure passes its limit only by more than this, so a value sitting on a limit
#: does not pass by an accident of rounding.
RESOLUTION_MM = 1e-3


def frame(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit ``axis`` (3,) and two unit vectors ``u, w`` (3,) completing a right-handed frame."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]
    u = np.cross(a, helper)
    u /= np.linalg.norm(u)
    return a, u, np.cross(a, u)


class Sections:
    """Sections of a closed mesh by the planes ``{x : (x - origin) . axis = s_k}``.

    ``segments[k]`` is ``(m, 2, 2)``: the section's segments in the plane's coordinates
    ``((x - origin) . u, (x - origin) . w)`` (the axis point is at 0, 0); ``edges[k]`` is
    ``(m, 2)``: the mesh edge (as an index into the mesh's unique edges) each end lies on.
    The levels are nudged by 1e-9 of the mesh size so that no vertex lies on a plane.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, origin: np.ndarray,
                 axis: np.ndarray, levels: np.ndarray):
        v = np.asarray(vertices, float) - np.asarray(origin, float)
        f = np.asarray(faces, int)
        a, u, w = frame(axis)
        h, pu, pw = v @ a, v @ u, v @ w
        size = float(np.ptp(v, axis=0).max())
        self.levels = np.asarray(levels, float) + 1e-9 * size * np.pi / 3
        # unique undirected edges of the mesh, each face's three edges as indices into them
        e = np.sort(np.stack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=1), axis=2)
        uniq, inv = np.unique(e.reshape(-1, 2), axis=0, return_inverse=True)
        face_edges = inv.reshape(-1, 3)
        hf = h[f]
        lo, hi = hf.min(axis=1), hf.max(axis=1)
        self.segments, self.edges = [], []
        for s in self.levels:
            crossing = np.flatnonzero((lo < s) & (hi > s))
            fe = face_edges[crossing]  # (m, 3) edges of each crossing face
            ea, eb = uniq[fe, 0], uniq[fe, 1]
            above = (h[ea] > s) != (h[eb] > s)  # which two of the three edges cross
            idx = np.argsort(~above, axis=1, kind="stable")[:, :2]
            ea, eb = np.take_along_axis(ea, idx, 1), np.take_along_axis(eb, idx, 1)
            lam = (s - h[ea]) / (h[eb] - h[ea])
            pts = np.stack([pu[ea] + lam * (pu[eb] - pu[ea]),
                            pw[ea] + lam * (pw[eb] - pw[ea])], axis=-1)
            self.segments.append(pts)
            self.edges.append(np.take_along_axis(fe, idx, 1))


def _crossings(segments: np.ndarray, point: np.ndarray, angles: np.ndarray
               ) -> np.ndarray:
    """Distances ``(K, m)`` from ``point`` (2,) along the rays at ``angles`` (K,) to where they
    cross the ``segments`` (m, 2, 2); inf where a ray does not cross a segment."""
    d = np.stack([np.cos(angles), np.sin(angles)], axis=1)  # (K, 2)
    p, q = segments[:, 0] - point, segments[:, 1] - point  # (m, 2)
    # side of the ray's line of each end; a segment crosses when its ends are on different
    # sides with "> 0" against "<= 0", so a crossing through a shared end counts once
    sp = d[:, None, 0] * p[None, :, 1] - d[:, None, 1] * p[None, :, 0]  # (K, m)
    sq = d[:, None, 0] * q[None, :, 1] - d[:, None, 1] * q[None, :, 0]
    cross = (sp > 0) != (sq > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = sp / (sp - sq)
        x = p[None] + lam[..., None] * (q - p)[None]  # (K, m, 2) crossing points
        r = np.einsum("kmj,kj->km", x, d)
    return np.where(cross & (r > 0), r, np.inf)


def ray_hits(segments: np.ndarray, point: np.ndarray, angles: np.ndarray) -> list[np.ndarray]:
    """Sorted distances from ``point`` (2,) at which the rays at ``angles`` (K,) cross the
    section's ``segments`` (m, 2, 2): a list of K arrays."""
    r = _crossings(segments, point, angles)
    return [np.sort(row[np.isfinite(row)]) for row in r]


def first_run(segments: np.ndarray, point: np.ndarray, angles: np.ndarray,
              reach: float = np.inf) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per ray (K,): whether ``point`` is inside the solid (odd number of crossings) and the
    first material interval ``[r_in, r_out]`` along it (r_in = 0 when inside; inf where the ray
    meets no section edge within ``reach`` of the point)."""
    n = len(angles)
    if len(segments) == 0:
        return np.zeros(n, bool), np.full(n, np.inf), np.full(n, np.inf)
    inside = len(ray_hits(segments, point, np.array([0.7853981 * np.sqrt(2)]))[0]) % 2 == 1
    near = segments[_segment_distance(segments, point) < reach]
    r = np.sort(_crossings(near, point, angles), axis=1) if len(near) else np.zeros((n, 0))
    r = np.concatenate([r, np.full((n, 2), np.inf)], axis=1)
    if inside:
        return np.ones(n, bool), np.zeros(n), r[:, 0]
    return np.zeros(n, bool), r[:, 0], r[:, 1]


def _segment_distance(segments: np.ndarray, point: np.ndarray) -> np.ndarray:
    """Distance ``(m,)`` of a 2D point to each segment (m, 2, 2)."""
    p, e = segments[:, 0] - point, segments[:, 1] - segments[:, 0]
    n2 = np.einsum("ij,ij->i", e, e)
    lam = np.clip(-np.einsum("ij,ij->i", p, e) / np.where(n2 > 0, n2, 1.0), 0.0, 1.0)
    return np.linalg.norm(p + lam[:, None] * e, axis=1)


def loops(segments: np.ndarray, edges: np.ndarray) -> list[np.ndarray]:
    """Indices of the segments of each closed loop of a section (connected components of the
    graph whose nodes are mesh edges and whose arcs are the segments)."""
    if len(edges) == 0:
        return []
    nodes, inv = np.unique(edges.ravel(), return_inverse=True)
    inv = inv.reshape(-1, 2)
    n = len(nodes)
    g = coo_matrix((np.ones(len(inv)), (inv[:, 0], inv[:, 1])), shape=(n, n))
    _, label = connected_components(g, directed=False)
    seg_label = label[inv[:, 0]]
    return [np.flatnonzero(seg_label == c) for c in np.unique(seg_label)]


def encloses(segments: np.ndarray, point: np.ndarray) -> bool:
    """Even-odd test of ``point`` (2,) against a closed loop's segments (m, 2, 2), by a ray in
    an irrational direction (no vertex hit in practice)."""
    return len(ray_hits(segments, point, np.array([0.7853981 * np.sqrt(2)]))[0]) % 2 == 1


def least_width(points: np.ndarray) -> float:
    """Least caliper width of the convex hull of 2D ``points`` (n, 2): exact, the minimum over
    hull edges of the farthest hull vertex from that edge's line."""
    pts = np.asarray(points, float)
    if len(pts) < 3 or np.linalg.matrix_rank(pts - pts.mean(0), tol=1e-9) < 2:
        return 0.0
    hv = pts[ConvexHull(pts).vertices]
    e = np.roll(hv, -1, axis=0) - hv
    nrm = np.stack([-e[:, 1], e[:, 0]], axis=1) / np.linalg.norm(e, axis=1)[:, None]
    proj = np.einsum("ij,kj->ik", nrm, hv) - np.einsum("ij,ij->i", nrm, hv)[:, None]
    return float(np.min(np.max(np.abs(proj), axis=1)))


def section_width(sec: Sections, k: int, point: np.ndarray) -> tuple[float, int]:
    """Least caliper width of the section loop ``k`` around ``point`` (2,) and the number of
    loops enclosing it (odd: the point is in the material; the innermost enclosing loop is
    measured). Width 0 when the point is not inside the material."""
    segs, edges = sec.segments[k], sec.edges[k]
    around = [ix for ix in loops(segs, edges) if encloses(segs[ix], point)]
    if len(around) % 2 == 0:
        return 0.0, len(around)
    widths = [least_width(segs[ix].reshape(-1, 2)) for ix in around]
    return float(min(widths)), len(around)


def area_above(tri_z: np.ndarray, areas: np.ndarray, level: float) -> np.ndarray:
    """Area of each triangle above the height ``level``: exact for a planar triangle (the
    height is linear on it), from its vertex heights ``tri_z`` (F, 3) and areas (F,)."""
    z = np.sort(tri_z, axis=1)
    z1, z2, z3 = z[:, 0], z[:, 1], z[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        low = (level - z1) ** 2 / ((z2 - z1) * (z3 - z1))
        high = 1.0 - (z3 - level) ** 2 / ((z3 - z1) * (z3 - z2))
    below = np.where(level <= z1, 0.0, np.where(level >= z3, 1.0,
                     np.where(level <= z2, low, high)))
    return areas * (1.0 - np.nan_to_num(below, nan=1.0))


def point_in_hull(hull_pts: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Signed distance ``(n,)`` of 2D ``pts`` to the boundary of the convex hull of
    ``hull_pts`` (positive inside)."""
    hv = hull_pts[ConvexHull(hull_pts).vertices]  # counter-clockwise
    e = np.roll(hv, -1, axis=0) - hv
    inward = np.stack([-e[:, 1], e[:, 0]], axis=1) / np.linalg.norm(e, axis=1)[:, None]
    d = np.einsum("ej,nj->ne", inward, pts) - np.einsum("ej,ej->e", inward, hv)[None, :]
    return d.min(axis=1)


def line_hits(vertices: np.ndarray, faces: np.ndarray, origin: np.ndarray,
              direction: np.ndarray) -> np.ndarray:
    """Sorted parameters ``u`` (n,) where the line ``origin + u direction`` crosses the mesh's
    triangles (Moller-Trumbore, both signs of u)."""
    tri = np.asarray(vertices, float)[np.asarray(faces, int)]
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    d = np.asarray(direction, float)
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-14
    inv = 1.0 / np.where(ok, det, 1.0)
    s = np.asarray(origin, float) - tri[:, 0]
    a = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    b = (q @ d) * inv
    u = np.einsum("ij,ij->i", e2, q) * inv
    ok &= (a >= 0) & (b >= 0) & (a + b <= 1)
    return np.sort(u[ok])
