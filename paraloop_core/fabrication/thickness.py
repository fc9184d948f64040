"""Local wall thickness of a printed part, measured on its mesh (issue 14: walls >= 2 mm).

The thickness at a surface point is the length of the chord along the inward normal: the
distance from the point to where a ray cast into the solid first leaves it (a "shape
diameter" with one ray). Points are sampled uniformly by area, so a percentile of the
thickness is a percentile over the part's surface. It is exact for the mesh at each sampled
point; the percentile is a sampling estimate (its standard error for the p-th percentile with
``n`` samples is about ``sqrt(p (1 - p) / n)`` in rank, 0.5 % of the surface for ``n = 2000``
at p = 5 %). Rays that start on a sharp convex edge can leave through the adjacent face at
once, so a low percentile, not the minimum, is the measure printers use.
"""

from __future__ import annotations

import numpy as np
import trimesh

#: Relative shortfall allowed for polygonized round walls (a 32-gon's chord through a face
#: centre is cos(pi/32) = 0.995 of the diameter).
POLYGON_TOLERANCE = 0.01

#: Hits closer than this fraction of the cap (0.04 mm for a 2 mm wall) are skipped: where a
#: boolean splits a long face, manifold3d's float32 vertices can fold sliver triangles over
#: each other by micrometres (random design 65: 11 % of a bar's surface read 0.007 mm). No
#: printer makes a wall that thin, so a real one is not missed in practice.
FOLD = 0.005

#: Rays per run (neighbours along the part) whose box pre-selects the triangles they test.
_RUN = 64


def _first_exit(origins: np.ndarray, dirs: np.ndarray, tris: np.ndarray,
                cap: float) -> np.ndarray:
    """Distance ``(n,)`` along unit ``dirs`` ``(n, 3)`` from ``origins`` ``(n, 3)`` to the first
    triangle of ``tris`` ``(f, 3, 3)`` hit at a distance in ``(FOLD cap, cap]`` (Moeller-Trumbore,
    both sides), else ``cap``. Only triangles whose bounding box meets the box of the ray's
    first ``cap`` are tested: the sparse pairs, not all rays times all faces."""
    lo_t, hi_t = tris.min(axis=1), tris.max(axis=1)
    ends = origins + cap * dirs
    lo_r, hi_r = np.minimum(origins, ends), np.maximum(origins, ends)
    scale = float(np.ptp(tris.reshape(-1, 3), axis=0).max())
    out = np.full(len(origins), float(cap))
    # rays in runs along the part's longest extent: each run's box meets few triangles, so
    # the ray-triangle box tests run on those only
    order = np.argsort(origins[:, int(np.argmax(np.ptp(origins, axis=0)))], kind="stable")
    lo_c, hi_c = lo_t.T.copy(), hi_t.T.copy()  # per component: no reductions over 3 columns
    for run in np.array_split(order, max(1, len(order) // _RUN)):
        lo_run, hi_run = lo_r[run].min(0), hi_r[run].max(0)
        box = (lo_run[0] <= hi_c[0]) & (hi_run[0] >= lo_c[0])
        for k in (1, 2):
            box &= (lo_run[k] <= hi_c[k]) & (hi_run[k] >= lo_c[k])
        cand = np.flatnonzero(box)
        near = np.ones((len(run), len(cand)), bool)
        for k in range(3):
            near &= (lo_r[run, k, None] <= hi_c[k, cand]) & (hi_r[run, k, None] >= lo_c[k, cand])
        r, f = np.nonzero(near)
        r_all, f = run[r], cand[f]
        o, d = origins[r_all], dirs[r_all]
        v0, e1, e2 = tris[f, 0], tris[f, 1] - tris[f, 0], tris[f, 2] - tris[f, 0]
        p = np.cross(d, e2)
        det = np.einsum("nk,nk->n", p, e1)
        ok = np.abs(det) > 1e-14 * scale * scale
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tv = o - v0
        a = np.einsum("nk,nk->n", tv, p) * inv
        q = np.cross(tv, e1)
        b = np.einsum("nk,nk->n", q, d) * inv
        dist = np.einsum("nk,nk->n", e2, q) * inv
        hit = ok & (a >= 0) & (b >= 0) & (a + b <= 1) & (dist > FOLD * cap) & (dist <= cap)
        np.minimum.at(out, r_all[hit], dist[hit])
    return out


def wall_thickness(mesh: trimesh.Trimesh, cap: float, count: int = 2000,
                   seed: int = 0) -> np.ndarray:
    """Local thickness ``(count,)`` (mesh units) at ``count`` area-uniform surface points of
    the closed ``mesh`` (module docstring), clipped to ``cap`` (> 0): a wall is only measured
    up to the thickness that matters, which keeps the ray casting local. Raises ValueError
    for an empty mesh, ``count < 1`` or ``cap <= 0``."""
    if count < 1 or len(mesh.faces) == 0 or not cap > 0:
        raise ValueError(f"wall_thickness needs a non-empty mesh, count >= 1 and cap > 0, got "
                         f"{len(mesh.faces)} faces, count {count}, cap {cap}")
    rng = np.random.default_rng(seed)
    area = mesh.area_faces
    face = rng.choice(len(area), size=count, p=area / area.sum())
    r1, r2 = rng.random((2, count))
    flip = r1 + r2 > 1  # fold the unit square onto the triangle: uniform barycentrics
    r1, r2 = np.where(flip, 1 - r1, r1), np.where(flip, 1 - r2, r2)
    tri = mesh.triangles[face]
    pts = tri[:, 0] + r1[:, None] * (tri[:, 1] - tri[:, 0]) + r2[:, None] * (tri[:, 2] - tri[:, 0])
    return _first_exit(pts, -mesh.face_normals[face], mesh.triangles, float(cap))


def thickness_summary(mesh: trimesh.Trimesh, wall_mm: float, count: int = 2000) -> dict:
    """JSON-ready ``p5_mm`` (5th percentile of :func:`wall_thickness`, mesh in mm, measured up
    to ``4 wall_mm``), ``min_mm``, ``samples`` and ``ok``: ``p5_mm`` at least ``wall_mm`` less
    :data:`POLYGON_TOLERANCE` (round surfaces are polygons, their chords a little short)."""
    d = wall_thickness(mesh, 4.0 * wall_mm, count)
    p5 = float(np.percentile(d, 5))
    return {"p5_mm": p5, "min_mm": float(d.min()), "samples": int(len(d)),
            "ok": bool(p5 >= (1.0 - POLYGON_TOLERANCE) * wall_mm)}


def walls(meshes: dict[str, trimesh.Trimesh], wall_mm: float) -> dict:
    """The report's ``walls``: :func:`thickness_summary` of every printed part (by name)
    against the profile's wall."""
    out = {name: thickness_summary(mesh, wall_mm) for name, mesh in meshes.items()}
    return {"wall_mm": wall_mm, "ok": all(w["ok"] for w in out.values()),
            "p5_mm": min(w["p5_mm"] for w in out.values()), "parts": out,
            "method": "chord along the inward normal at 2000 area-uniform surface points per "
                      "part (exact on the mesh; the percentile is a sampling estimate)"}
