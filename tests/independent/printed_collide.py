"""Clearance of the printed parts over the cycle (independent of paraloop_core's verification).

Every pair of links without a common joint (each link with the steel pieces of its joint j,
which turn about that joint's axis), and the still base (plate, rod, cap: with the grounded
link) against each moving link that does not turn on the rod, is measured at >= 1440
parameters over the whole cycle (t = inf included) by ``manifold3d``'s ``min_gap``: the exact
distance between the two triangle meshes (float32 vertices: ~2e-5 mm), searched up to a
length. A pair's sample is measured only where spheres bounding groups of its triangles
(a sound lower bound) come within that length; lengths 2, 5 mm are tried in turn, so the least
sampled distance is exact when below 5 mm; farther pairs report the distance at the sample
where two surface points come nearest (exact up to 25 mm, beyond: those points' distance), and
``at_least_mm`` = 5 holds at every sample. Between
samples the distance is refined by a golden-section search in the parameter around the least
sample; ``step_mm`` is how far any vertex moves relative to the other part between the
neighbouring samples there (the sampling's resolution).
"""

from __future__ import annotations

import manifold3d as m3
import numpy as np
import trimesh
from scipy.cluster.vq import kmeans2
from scipy.optimize import minimize_scalar

from .dense_check import _key
from .meshgeom import RESOLUTION_MM
from .printed_kin import key_to_t, parameters, relative_motion

#: Least distance (mm) between parts without a common joint (issue 26).
LIMIT_MM = 1.0
#: Search lengths (mm) of the exact distance, tried in turn.
SEARCH_MM = (2.0, 5.0)
#: Farther than this (mm) a pair's figure is the distance of two of its surface points.
FIGURE_MM = 25.0
#: Parameters sampled over the cycle.
N_SAMPLES = 1440
#: Triangle groups per part for the bounding spheres, and their triangles' longest edge (mm).
N_GROUPS = 64
GROUP_EDGE_MM = 8.0
#: Longest triangle edge (mm) of the meshes given to min_gap.
SOLID_EDGE_MM = 16.0


class Body:
    """Parts in the home frame (mm) moving with link ``link``: their union as a manifold and
    bounding spheres of groups of their triangles, each with a vertex of its group."""

    def __init__(self, name: str, meshes: list, link: int):
        self.name, self.link = name, link
        solids = [_solid(m) for m in meshes]
        self.solid = m3.Manifold.batch_boolean(solids, m3.OpType.Add) if len(solids) > 1 \
            else solids[0]
        mesh = trimesh.util.concatenate(meshes)
        self.vertices = np.asarray(mesh.vertices, float)
        # long triangles (a bar's faces) are split first so that the spheres stay small
        v, f = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, max_edge=GROUP_EDGE_MM)
        tri = v[f]
        cent = tri.mean(axis=1)
        centers, label = kmeans2(cent, min(N_GROUPS, len(cent)), seed=1, minit="++")
        used = np.unique(label)
        self.centers = centers[used]
        # each sphere holds its triangles whole (a triangle lies in the hull of its corners)
        far = np.linalg.norm(tri - centers[label][:, None, :], axis=2).max(axis=1)
        self.radii = np.array([far[label == c].max() for c in used])
        self.reps = np.array([tri[label == c][0, 0] for c in used])  # a surface point each


def _solid(mesh: trimesh.Trimesh) -> m3.Manifold:
    """The mesh as a manifold, its long triangles split (the same surface; min_gap's bounding
    boxes of long thin triangles are large and slow it down tenfold)."""
    v, f = trimesh.remesh.subdivide_to_size(mesh.vertices, mesh.faces, max_edge=SOLID_EDGE_MM)
    solid = m3.Manifold(m3.Mesh(vert_properties=np.asarray(v, np.float32),
                                tri_verts=np.asarray(f, np.uint32)))
    if solid.status() != m3.Error.NoError:
        raise ValueError(f"not a closed manifold mesh: {solid.status()}")
    return solid


def _placed(body: Body, rot: np.ndarray, tr: np.ndarray) -> m3.Manifold:
    return body.solid.transform(np.hstack([rot, tr[:, None]]))


def _distances(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Distances ``(T, n, m)`` between points ``x`` ``(T, n, 3)`` and ``y`` ``(m, 3)``."""
    d2 = (np.einsum("tni,tni->tn", x, x)[:, :, None] + np.einsum("mi,mi->m", y, y)[None, None]
          - 2.0 * np.einsum("tni,mi->tnm", x, y))
    return np.sqrt(np.maximum(d2, 0.0))


class Pair:
    """Motion of body ``a`` in body ``b``'s frame along the cycle."""

    def __init__(self, ex, a: Body, b: Body):
        self.ex, self.a, self.b = ex, a, b

    def relative(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rot, tr = relative_motion(self.ex, t, self.b.link)
        return rot[:, self.a.link], tr[:, self.a.link]

    def gap(self, t: float, search: float) -> float:
        rot, tr = self.relative(np.array([t]))
        return float(_placed(self.a, rot[0], tr[0]).min_gap(self.b.solid, search))

    def bounds(self, rot: np.ndarray, tr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sound lower bounds ``(T,)`` of the distance (the spheres) and upper bounds (the
        distance of two surface points, one per group)."""
        ca = np.einsum("tij,kj->tki", rot, self.a.centers) + tr[:, None]
        low = _distances(ca, self.b.centers) - self.a.radii[None, :, None] \
            - self.b.radii[None, None, :]
        ra = np.einsum("tij,kj->tki", rot, self.a.reps) + tr[:, None]
        return low.min(axis=(1, 2)), _distances(ra, self.b.reps).min(axis=(1, 2))


def pair_minimum(pair: Pair, t: np.ndarray) -> dict:
    """Least distance of a pair over the sorted samples ``t``, refined around its argument."""
    rot, tr = pair.relative(t)
    lb, ub = pair.bounds(rot, tr)
    best, k_best = np.inf, None
    for search in SEARCH_MM:
        for k in np.flatnonzero(lb < search):
            g = float(_placed(pair.a, rot[k], tr[k]).min_gap(pair.b.solid, search))
            if g < search and g < best:
                best, k_best = g, int(k)
        if k_best is not None:
            break
    out = {"parts": [pair.a.name, pair.b.name], "samples": len(t)}
    if k_best is None:  # every sample is farther than the longest search length
        k = int(np.argmin(ub))
        near = min(float(ub[k]), FIGURE_MM)  # beyond: the two surface points' distance
        at = float(_placed(pair.a, rot[k], tr[k]).min_gap(pair.b.solid, near + 0.01))
        out.update(min_mm=min(at, float(ub[k])), exact=False, at_least_mm=SEARCH_MM[-1],
                   t=float(t[k]))
        return out
    # refine between the neighbouring samples (in the cyclic key of the projective line)
    key = _key(t)
    n = len(t)
    lo, hi = key[(k_best - 1) % n], key[(k_best + 1) % n]
    if hi < lo:  # the neighbours straddle t = inf (key -2 == 2)
        hi += 4.0
    search = best + 1.0
    res = minimize_scalar(lambda x: pair.gap(float(key_to_t((x + 2) % 4 - 2)), search),
                          bounds=(lo, hi), method="bounded", options={"xatol": 1e-6})
    refined = min(best, float(res.fun))
    nb = np.array([(k_best - 1) % n, k_best, (k_best + 1) % n])
    moved = np.einsum("tij,vj->tvi", rot[nb], pair.a.vertices) + tr[nb][:, None]
    step = float(np.max(np.linalg.norm(np.diff(moved, axis=0), axis=-1)))
    out.update(min_mm=refined, sampled_min_mm=best, exact=True, t=float(t[k_best]),
               step_mm=step)
    return out


def _cylinder(a, b, r: float, n: int = 48) -> trimesh.Trimesh:
    """A prism around the cylinder of radius ``r`` from ``a`` to ``b`` (circumscribed: never
    thinner than the cylinder)."""
    return trimesh.creation.cylinder(radius=r / np.cos(np.pi / n), sections=n,
                                     segment=np.array([a, b], float))


def _hardware(ex, link: int) -> list[trimesh.Trimesh]:
    """Steel pieces of joint ``link`` (screw, head, washer, nut: circumscribing cylinders; the
    grounding rod is a body of the base), carried by link ``link`` (they turn about its
    joint's axis, which both of the joint's links keep)."""
    jt = ex.report["joints"][link]
    o, a = np.asarray(jt["origin_mm"], float), np.asarray(jt["axis"], float)
    return [_cylinder(o + a * p["s_mm"][0], o + a * p["s_mm"][1], p["radius_mm"])
            for p in jt.get("pieces", []) if not p.get("printed") and p["role"] != "rod"]


def check_collisions(ex, rod: dict | None = None) -> tuple[dict, list[str]]:
    """Figures and failures of the clearance check; ``rod`` (home mm ``bottom``, ``top``,
    ``radius_mm``) adds the grounding rod to the still base."""
    carried = [p for p in ex.report.get("parts", [])  # printed pieces other than the rod's cap
               if p["role"] not in ("link", "base", "link piece")
               and not p["name"].startswith("rod_cap")]
    bodies = [Body(f"link_{i}", [m] + _hardware(ex, i) + [ex.mesh(p["name"]) for p in carried
                                                          if int(p["link"]) == i], i)
              for i, m in enumerate(ex.links)]
    g = ex.grounded
    pairs = [Pair(ex, bodies[i], bodies[k]) for i in range(6) for k in range(i + 1, 6)
             if (k - i) % 6 not in (1, 5)]
    base = ex.report.get("base") or {}
    if g is not None and base.get("stands") is not None:
        jt = ex.report["joints"][int(base["rod_joint"])] if base.get("rod_joint") is not None \
            else None
        turning = set() if jt is None else {jt["joint"], (jt["joint"] + 1) % 6} - {g}
        extra = [(Body("base_plate", [ex.mesh("base_plate")], g), set())]
        if rod is not None:
            steel = _cylinder(rod["bottom"], rod["top"], rod["radius_mm"])
            extra.append((Body("rod", [steel], g), turning))
        for part in ex.report.get("parts", []):
            if part["name"].startswith("rod_cap"):  # glued on the still rod
                extra.append((Body(part["name"], [ex.mesh(part["name"])], g), turning))
        for body, skip in extra:
            pairs += [Pair(ex, bodies[i], body) for i in range(6) if i != g and i not in skip]
    t = parameters(ex.jf, N_SAMPLES)
    rows = [pair_minimum(p, t) for p in pairs]
    fails = [f"collision: {r['parts'][0]} and {r['parts'][1]} come {r['min_mm']:.2f} mm apart "
             f"(t = {r['t']:.4g}) < {LIMIT_MM:g} mm" for r in rows
             if not r["min_mm"] >= LIMIT_MM + RESOLUTION_MM]
    links = [r["min_mm"] for r in rows if r["parts"][1].startswith("link_")]
    return {"pairs": rows, "samples": len(t), "min_non_adjacent_mm": min(links)}, fails
