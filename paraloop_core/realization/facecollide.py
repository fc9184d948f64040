"""Exact edge-face collision checks and minimum distances over the whole cycle (Sec. 5.1).

Setting as in :mod:`clearance` (MATH §11-12): a triangle mesh P is fixed in link i's home frame,
a segment of link j moves by the relative motion ``R(t)`` of degree k, t in ``R u {inf}``.

**Collision.** The set of t where a moving segment meets a fixed triangle is closed; at each of
its boundary points the contact is unstable, which for a segment and a triangle means that
(a) the segment meets a triangle *edge* (the two lines meet: a real root of the reciprocal
product ``Om(t)``, degree 2k, :func:`collision.pair_collisions`), or (b) a segment *endpoint*
lies on the face (a real root of the plane polynomial ``g(t) = n.X(t) - (n.a) N(t)``, degree
2k, with the in-face test). A set without boundary points is the whole cycle, caught at
t = inf. So checking edges against the segment (both ways: triangle vertices on the segment
are edge-edge contacts) and endpoints against faces is exact. Face-face contact of two solids
likewise starts with an edge crossing a face, so these tests suffice for any pair of triangles.
Collision-free surfaces can still *contain* a segment; :func:`inside_closed` tests one point.

**Minimum distance.** ``dist(P, B(t))`` is attained between a triangle edge and the segment
(exact via :func:`clearance.min_distance_batch`) or between a segment endpoint and a face
interior, where it equals ``|g/N|`` (unit normal): candidates are the roots of ``g'N - gN'``
(top coefficient cancels) and of g, plus t = inf; at every candidate the true point-triangle
distance is evaluated, so the minimum over candidates is exact. A segment piercing a face
interior has distance 0; by the boundary argument above that is an edge or endpoint zero, or
it pierces at t = inf, which is tested directly.
"""

from __future__ import annotations

import numpy as np

from paraloop_core.algebra import poly
from paraloop_core.realization.clearance import (
    MotionData,
    chart_roots,
    dot,
    min_distance_batch,
    moving_segments,
    pder,
    pmul,
    segment_distance,
    segments_at,
    with_home,
)
from paraloop_core.realization.collision import pair_collisions
from paraloop_core.tolerance import TOL


def _in_face(y: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray, n: np.ndarray
             ) -> np.ndarray:
    """Barycentric test: the projection of y lies on the inner side of all three edges."""
    return ((dot(np.cross(b - a, y - a), n) >= 0) & (dot(np.cross(c - b, y - b), n) >= 0)
            & (dot(np.cross(a - c, y - c), n) >= 0))


def point_triangle_distance(x: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Distance ``(...)`` of points ``(..., 3)`` to solid triangles ``(..., 3, 3)`` (broadcast)."""
    a, b, c = tri[..., 0, :], tri[..., 1, :], tri[..., 2, :]
    n = np.cross(b - a, c - a)
    nn = dot(n, n)
    h = dot(x - a, n) / nn  # signed height in units of |n|
    inside = _in_face(x, a, b, c, n)  # the cross products ignore the normal component of x
    plane = np.abs(h) * np.sqrt(nn)
    edge = np.minimum(np.minimum(segment_distance(x, x, a, b), segment_distance(x, x, b, c)),
                      segment_distance(x, x, c, a))
    return np.where(inside, plane, edge)


def segment_triangle_distance(seg: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Distance ``(...)`` between segments ``(..., 2, 3)`` and solid triangles ``(..., 3, 3)``."""
    p, q = seg[..., 0, :], seg[..., 1, :]
    a, b, c = tri[..., 0, :], tri[..., 1, :], tri[..., 2, :]
    n = np.cross(b - a, c - a)
    hp, hq = dot(p - a, n), dot(q - a, n)
    # a proper crossing of the plane inside the triangle: distance 0
    w = np.where(hp != hq, hp / np.where(hp != hq, hp - hq, 1.0), 0.0)
    cross = p + w[..., None] * (q - p)
    crossing = (hp * hq <= 0) & (hp != hq) & _in_face(cross, a, b, c, n)
    best = np.minimum(point_triangle_distance(p, tri), point_triangle_distance(q, tri))
    for u, v in ((a, b), (b, c), (c, a)):
        best = np.minimum(best, segment_distance(u, v, p, q))
    return np.where(crossing, 0.0, best)


def _plane_polys(md: MotionData, idx: np.ndarray, tri: np.ndarray, x: np.ndarray):
    """``g`` ``(B, 2k+1)`` (signed height of moving points ``x`` ``(B, 3)`` over the plane of
    ``tri`` ``(B, 3, 3)``, unit normal, times N) and ``N`` ``(B, 2k+1)``."""
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    xh = np.concatenate([x, np.ones((len(x), 1))], axis=1)
    xt = np.einsum("bcjn,bj->bcn", md.points[idx], xh)
    nrm = md.norm[idx]
    return np.einsum("bc,bcn->bn", n, xt) - dot(n, tri[:, 0])[:, None] * nrm, nrm


def face_segment_hits(md: MotionData, idx: np.ndarray, tri: np.ndarray, seg: np.ndarray
                      ) -> np.ndarray:
    """Vertex-face part of the collision test, mask ``(B,)``: a moving segment endpoint crosses
    the fixed triangle ``(B, 3, 3)``, or the segment ``(B, 2, 3)`` pierces it at t = inf."""
    nb = len(idx)
    def roots_in(m: MotionData) -> np.ndarray:
        g, _ = _plane_polys(m, np.repeat(idx, 2), np.repeat(tri, 2, axis=0), seg.reshape(-1, 3))
        return poly.real_poly_roots(g, rtol=TOL.zero).real.reshape(2 * nb, -1)

    roots = chart_roots(md, roots_in).reshape(nb, 2, -1)
    cand = np.where(np.isnan(roots), np.inf, roots)  # (B, 2, K): per endpoint
    moved = segments_at(md, idx, seg, cand.reshape(nb, -1)).reshape(nb, 2, -1, 2, 3)
    x = np.stack([moved[:, 0, :, 0], moved[:, 1, :, 1]], axis=1)  # each endpoint at its roots
    a, b, c = (tri[:, None, None, v] for v in range(3))
    n = np.cross(b - a, c - a)
    size = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1) + np.ptp(tri, axis=1).max(axis=1)
    # real parts of complex roots are no crossings: the height must vanish there too
    height = np.abs(dot(x - a, n)) / np.linalg.norm(n, axis=-1)
    on_face = (height <= TOL.residual * size[:, None, None]) & _in_face(x, a, b, c, n)
    home = moving_segments(md, idx, seg, np.full((nb, 1), np.inf))[:, 0]
    return on_face.any(axis=(1, 2)) | (segment_triangle_distance(home, tri) <= 0.0)


def vertex_face_min_distance(md: MotionData, idx: np.ndarray, tri: np.ndarray, x: np.ndarray
                             ) -> tuple[np.ndarray, np.ndarray]:
    """Exact minimum over the cycle of the distance between moving points ``x`` ``(B, 3)`` and
    fixed triangles ``(B, 3, 3)`` where the foot lies inside the face (elsewhere the value is a
    true, larger point-triangle distance). Returns ``(dist (B,), t (B,))``."""
    def roots_in(m: MotionData) -> np.ndarray:
        g, nrm = _plane_polys(m, idx, tri, x)
        crit = (pmul(pder(g), nrm) - pmul(g, pder(nrm)))[:, :-1]  # top coefficient cancels
        return np.concatenate([poly.real_poly_roots(crit, rtol=TOL.zero),
                               poly.real_poly_roots(g, rtol=TOL.zero)], axis=1).real

    cand = with_home(chart_roots(md, roots_in))
    xx = np.repeat(x[:, None], 2, axis=1)
    moved = segments_at(md, idx, xx, cand)[..., 0, :]
    dist = point_triangle_distance(moved, tri[:, None])
    best = np.argmin(dist, axis=1)
    rows = np.arange(len(idx))
    return dist[rows, best], md.to_t(cand[rows, best])


def sphere_bound(md: MotionData, idx: np.ndarray, vertices: np.ndarray, seg: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Lower bound ``(S,)`` of ``dist(P, B(t))`` over the cycle from P's bounding sphere (exact
    minimum distance of its centre to the moving segment minus its radius) and where the
    centre is closest ``(S,)``."""
    centre = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    radius = np.linalg.norm(vertices - centre, axis=1).max()
    point = np.broadcast_to(centre, (len(idx), 2, 3))  # a zero-length fixed segment
    dist, t = min_distance_batch(md, idx, point, seg)
    return dist - radius, t


def mesh_segment_collisions(md: MotionData, idx: np.ndarray, vertices: np.ndarray,
                            faces: np.ndarray, edges: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """Mask ``(S,)``: moving segments ``(S, 2, 3)`` (motions ``idx`` ``(S,)`` of ``md``) ever
    touch the fixed mesh (``vertices`` ``(V, 3)`` in the fixed link's home frame, ``faces``
    ``(F, 3)``, unique ``edges`` ``(E, 2)``). Segments that stay outside P's bounding sphere are
    cleared first; the rest are vectorized over all segment-edge/face items."""
    hit = np.zeros(len(idx), dtype=bool)
    near = np.flatnonzero(sphere_bound(md, idx, vertices, seg)[0] <= 0.0)
    if near.size:
        hit[near] = _mesh_hits(md, idx[near], vertices, faces, edges, seg[near])
    return hit


def _mesh_hits(md: MotionData, idx: np.ndarray, vertices: np.ndarray, faces: np.ndarray,
               edges: np.ndarray, seg: np.ndarray) -> np.ndarray:
    ns, ne, nf = len(idx), len(edges), len(faces)
    hit_e, _ = pair_collisions(md, np.repeat(idx, ne), np.tile(vertices[edges], (ns, 1, 1)),
                               np.repeat(seg, ne, axis=0))
    hit = hit_e.reshape(ns, ne).any(axis=1)
    rest = np.flatnonzero(~hit)  # faces only where no edge contact was found
    if rest.size:
        hit_f = face_segment_hits(md, np.repeat(idx[rest], nf),
                                  np.tile(vertices[faces], (rest.size, 1, 1)),
                                  np.repeat(seg[rest], nf, axis=0))
        hit[rest] = hit_f.reshape(rest.size, nf).any(axis=1)
    return hit


def mesh_segment_clearance(md: MotionData, idx: np.ndarray, vertices: np.ndarray,
                           faces: np.ndarray, edges: np.ndarray, seg: np.ndarray, need: float
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(dist, t, exact)`` ``(S,)``: where P's bounding sphere already keeps ``need`` away,
    its certified lower bound (``exact`` False), else the exact minimum over the cycle."""
    dist, t = sphere_bound(md, idx, vertices, seg)
    exact = dist < need
    if np.any(exact):
        dist[exact], t[exact] = mesh_segment_min_distance(md, idx[exact], vertices, faces, edges,
                                                          seg[exact])
    return dist, t, exact


def mesh_segment_min_distance(md: MotionData, idx: np.ndarray, vertices: np.ndarray,
                              faces: np.ndarray, edges: np.ndarray, seg: np.ndarray
                              ) -> tuple[np.ndarray, np.ndarray]:
    """Exact minimum over the cycle of ``dist(P, B(t))`` for moving segments ``(S, 2, 3)``;
    returns ``(dist (S,), t (S,))`` (0 if they collide, ``t = inf`` at home)."""
    ns, ne, nf = len(idx), len(edges), len(faces)
    de, te = min_distance_batch(md, np.repeat(idx, ne), np.tile(vertices[edges], (ns, 1, 1)),
                                np.repeat(seg, ne, axis=0))
    # each face against both endpoints: items ordered (segment, face, endpoint)
    tri = np.repeat(np.tile(vertices[faces], (ns, 1, 1)), 2, axis=0)
    pts = np.repeat(seg, nf, axis=0).reshape(-1, 3)
    dv, tv = vertex_face_min_distance(md, np.repeat(idx, 2 * nf), tri, pts)
    # a segment piercing a face for the whole cycle has no contact event: test t = inf
    home = moving_segments(md, idx, seg, np.full((ns, 1), np.inf))
    dh = segment_triangle_distance(home, vertices[faces][None]).min(axis=1, keepdims=True)
    dist = np.concatenate([de.reshape(ns, ne), dv.reshape(ns, 2 * nf), dh], axis=1)
    t = np.concatenate([te.reshape(ns, ne), tv.reshape(ns, 2 * nf), np.full((ns, 1), np.inf)],
                       axis=1)
    best = np.argmin(dist, axis=1)
    rows = np.arange(ns)
    return dist[rows, best], t[rows, best]


def inside_closed(vertices: np.ndarray, faces: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Mask ``(...)``: points ``(..., 3)`` strictly inside the closed mesh (generalized winding
    number |w| > 1/2, Van Oosterom-Strackee solid angles; orientation-independent)."""
    d = vertices[faces][None] - np.asarray(x, np.float64).reshape(-1, 1, 1, 3)  # (X, F, 3, 3)
    a, b, c = d[..., 0, :], d[..., 1, :], d[..., 2, :]
    la, lb, lc = (np.linalg.norm(v, axis=-1) for v in (a, b, c))
    num = dot(a, np.cross(b, c))
    den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb
    w = np.sum(np.arctan2(num, den), axis=-1) / (2.0 * np.pi)
    return (np.abs(w) > 0.5).reshape(np.shape(x)[:-1])

