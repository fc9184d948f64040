"""Voxel design spaces -> smooth closed triangle meshes that stay inside the certified region.

Pipeline (all vectorized): erode the occupancy by ``E = sqrt(3) a + h + m + q`` (pitch ``a``,
half-diagonal ``h``, smoothing limit ``m``, simplification tolerance ``q``), take the signed
distance field of the eroded set, extract its zero level by **marching tetrahedra** (six Kuhn
tetrahedra per cube, vertices merged per grid edge: a closed 2-manifold because the field is
never zero at grid points), Taubin-smooth with every vertex clamped to within ``m`` of its
marching position, and simplify with manifold3d (surfaces move by less than ``q``, its
documented guarantee).

Containment (why the surface stays inside the carved region, the union of balls of radius
``h`` about the kept centres): a marching-tetrahedra solid lies in tetrahedra with an inside
corner, so within ``sqrt(3) a`` (a cube diagonal) of an eroded centre; smoothing and
simplification move the surface by at most ``m + q``; and every point within ``E - h`` of an
eroded centre lies in the uneroded region (its nearest grid centre is within ``h`` and within
``E`` of the eroded centre, hence occupied). So the mesh solid is inside the region whenever
``sqrt(3) a + m + q <= E - h``.
"""

from __future__ import annotations

import itertools

import manifold3d as m3d
import numpy as np
from scipy import ndimage, sparse

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication.voxelspace import VoxelSpace

#: Corner k of a cube has offset bits (x, y, z) = (k >> 2, k >> 1, k) & 1.
_CORNERS = np.array([[(k >> 2) & 1, (k >> 1) & 1, k & 1] for k in range(8)])
#: Kuhn triangulation: six tetrahedra along the main diagonal, consistent across cube faces.
_TETS = np.array([[0, 1 << (2 - p[0]), (1 << (2 - p[0])) | (1 << (2 - p[1])), 7]
                  for p in itertools.permutations(range(3))])


def _triangles(inside: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per case: ``(mask over tets, edges (n, 3 or 6, 2) local corner pairs)``; helper of
    :func:`marching_tetrahedra`."""
    code = inside @ (1 << np.arange(4))
    out = []
    for case in range(1, 15):
        sel = code == case
        if not sel.any():
            continue
        ins = [k for k in range(4) if case >> k & 1]
        outs = [k for k in range(4) if not case >> k & 1]
        if len(ins) in (1, 3):
            v, others = (ins[0], outs) if len(ins) == 1 else (outs[0], ins)
            edges = [[(v, o) for o in others]]
        else:
            (i1, i2), (o1, o2) = ins, outs
            edges = [[(i1, o1), (i1, o2), (i2, o2)], [(i1, o1), (i2, o2), (i2, o1)]]
        out.append((sel, np.array(edges)))
    return out


def marching_tetrahedra(field: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Zero level of ``field`` ``(X, Y, Z)`` (positive inside, never exactly zero) as
    ``(vertices (V, 3) in index units, faces (F, 3))``, outward oriented."""
    f = np.asarray(field, float)
    inside = f > 0
    shape = np.array(f.shape)
    corner_in = np.stack([inside[tuple(slice(c, c + n - 1) for c, n in
                                       zip(off, shape, strict=True))] for off in _CORNERS], -1)
    active = np.argwhere(corner_in.any(-1) & ~corner_in.all(-1))
    if not len(active):
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    pos = active[:, None, None, :] + _CORNERS[_TETS][None]  # (N, 6, 4, 3)
    pos = pos.reshape(-1, 4, 3)
    lin = np.ravel_multi_index(tuple(np.moveaxis(pos, -1, 0)), f.shape)  # (M, 4)
    val = f.reshape(-1)[lin]
    tris, tet_of = [], []
    for sel, edges in _triangles(val > 0):
        idx = np.nonzero(sel)[0]
        for tri in edges:  # one or two triangles per tetrahedron
            ga, gb = lin[idx][:, tri[:, 0]], lin[idx][:, tri[:, 1]]
            tris.append(np.stack([np.minimum(ga, gb), np.maximum(ga, gb)], -1))
            tet_of.append(idx)
    tri_edges = np.concatenate(tris)  # (F, 3, 2) global grid indices of edge ends
    tet_of = np.concatenate(tet_of)
    keys = tri_edges[..., 0] * f.size + tri_edges[..., 1]
    uniq, faces = np.unique(keys.reshape(-1), return_inverse=True)
    faces = faces.reshape(-1, 3)
    ea, eb = uniq // f.size, uniq % f.size
    fa, fb = f.reshape(-1)[ea], f.reshape(-1)[eb]
    # Clamp away from the ends: no zero-area triangles; the vertex stays on its grid edge.
    t = np.clip(fa / (fa - fb), 0.02, 0.98)[:, None]
    pa = np.stack(np.unravel_index(ea, f.shape), -1)
    pb = np.stack(np.unravel_index(eb, f.shape), -1)
    verts = pa + t * (pb - pa)
    # Orient outward: normal along (outside corners' mean - inside corners' mean).
    tin = (val[tet_of] > 0)[..., None]
    cpos = pos[tet_of]
    outward = (cpos * ~tin).sum(1) / (~tin).sum(1) - (cpos * tin).sum(1) / tin.sum(1)
    v = verts[faces]
    normal = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    flip = np.sum(normal * outward, -1) < 0
    faces[flip] = faces[flip][:, ::-1]
    return verts, faces


def taubin_smooth(verts: np.ndarray, faces: np.ndarray, limit: float, iterations: int = 10,
                  lam: float = 0.5, mu: float = -0.53) -> np.ndarray:
    """Taubin smoothing of ``verts`` ``(V, 3)``; every vertex stays within ``limit`` of its
    input position (clamped after each step), so the surface moves by at most ``limit``."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    n = len(verts)
    adj = sparse.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)).tocsr()
    adj = ((adj + adj.T) > 0).astype(float)
    deg = np.asarray(adj.sum(1)).ravel()
    walk = sparse.diags(1.0 / np.maximum(deg, 1)) @ adj
    v0, v = verts, verts.copy()
    for _ in range(iterations):
        for w in (lam, mu):
            v = v + w * (walk @ v - v)
            d = v - v0
            norm = np.linalg.norm(d, axis=1, keepdims=True)
            v = v0 + d * np.minimum(1.0, limit / np.maximum(norm, 1e-300))
    return v


def space_mesh(space: VoxelSpace, smooth_limit: float = 0.5, iterations: int = 10,
               stride: int = 1, simplify: float = 0.25) -> tuple[np.ndarray, np.ndarray]:
    """Smooth closed mesh ``(vertices (V, 3) home frame, faces (F, 3))`` inside the carved
    region of ``space`` (module docstring); the field is sampled every ``stride`` voxels
    (coarser mesh, cube diagonal ``sqrt(3) stride a`` in the erosion); ``smooth_limit`` and the
    ``simplify`` tolerance are in sampled cells. Raises :class:`FabricationError`
    (``empty-space``) when nothing survives the erosion."""
    if stride < 1 or not (smooth_limit >= 0 and simplify >= 0):
        raise FabricationError("stride must be >= 1, smooth_limit and simplify >= 0",
                               "bad-parameters")
    a = space.pitch * stride
    m, q = smooth_limit * a, simplify * a
    erosion = np.sqrt(3.0) * a + space.half_diagonal + m + q
    occ = np.pad(space.occupancy, 2 * stride)
    eroded = ndimage.distance_transform_edt(occ, sampling=space.pitch) > erosion
    if not eroded.any():
        raise FabricationError(
            f"design space too thin to mesh: nothing is deeper than {erosion:.4g} "
            "(design units) inside it; raise the resolution", "empty-space")
    field = ndimage.distance_transform_edt(eroded) - ndimage.distance_transform_edt(~eroded)
    verts, faces = marching_tetrahedra(field[::stride, ::stride, ::stride])
    verts = taubin_smooth(verts, faces, smooth_limit, iterations)
    home = (verts * a - 2.0 * stride * space.pitch) @ space.frame[:3, :3].T + space.frame[:3, 3]
    if q > 0:
        man = m3d.Manifold(m3d.Mesh(home.astype(np.float32), faces.astype(np.uint32)))
        out = man.simplify(q).to_mesh()
        home, faces = np.asarray(out.vert_properties[:, :3], float), np.asarray(out.tri_verts)
    return home, faces
