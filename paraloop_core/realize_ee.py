"""Realization with an end-effector (paper Sec. 5.1 "End-effector integration", Fig. 7, 9).

The end link 3 becomes ``S_3 L + P + R E_3``: the polyhedron P (at home, base/world frame)
and two bars from ``S_3`` (on ``A_2``) to the vertex L of P and from the vertex R to ``E_3``
(on ``A_3``). L and R never move; the initial polyline is eq. 11 with the end link routed
``V_2 L R V_3`` (:func:`endeffector.initial_polyline`), and ``V_2``, ``V_3`` shift like the
other vertices unless fixed (Fig. 9 fixes them too). The search of
:func:`realize.realize` runs unchanged (same candidates, order and offset sequences) with
extra exact checks: thin stage, the two bars against the thin segments they do not touch and P
against the segments of links 0, 1, 2, 4, 5 (:mod:`facecollide`); step 4, every pair of
:data:`offsetting.OFFSET_PAIRS` without the dropped bar ``S_3E_3`` (>= 2 rho), the bars
``S_3L``, ``RE_3`` against the other edges (>= 2 rho; like consecutive bars, ``S_3L``/``S_2E_2``
and ``RE_3``/``S_4E_4`` are skipped) and P against every other edge (>= ``ee_clearance``,
default rho: no bar cylinder enters P). Edges fixed in link 3 (pins on ``A_2``, ``A_3``) are
checked once at home. A closed P must not contain any other edge (one point each, at home).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import dq, loops
from .clearance import min_distance_batch, segment_distance
from .collision import THIN_PAIRS, pair_collisions
from .endeffector import EndEffector, ee_length, initial_polyline
from .errors import RealizationError
from .facecollide import (
    PairMotions,
    inside_closed,
    mesh_segment_clearance,
    mesh_segment_collisions,
    segment_triangle_distance,
)
from .offsetting import DIGITS, OFFSET_PAIRS, OFFSET_WAYS, LoopMotions, OffsetSearch, sequence_order
from .realize import Realization, check_params

_MESH = -1  # part code of P in the pair tables


def _cyc(a: int, b: int) -> int:
    return min((b - a) % 6, (a - b) % 6)


def _edge_link(e: int) -> int:
    """Link carrying edge e, relative to link 3: a pin takes the neighbour closer to 3."""
    i = e // 2
    return i if e % 2 == 0 else min((i, (i + 1) % 6), key=lambda j: _cyc(3, j))


def _thin_rows() -> list[tuple[tuple[int, int], tuple[int, int], tuple[int, int]]]:
    """Thin stage rows ``(fixed part, moving segment, (link a, link b))``; points 0..5 are the
    thin vertices, 6 = L, 7 = R; a part ``(_MESH, _MESH)`` is P."""
    seg = {i: ((i - 1) % 6, i) for i in range(6)}
    rows = [(seg[i], seg[j], (i, j)) for i, j in THIN_PAIRS if 3 not in (i, j)]
    rows += [((2, 6), seg[j], (3, j)) for j in (0, 1, 4, 5)]  # V_2 L
    rows += [((7, 3), seg[j], (3, j)) for j in (0, 1, 2, 5)]  # R V_3
    return rows + [((_MESH, _MESH), seg[j], (3, j)) for j in (0, 1, 2, 4, 5)]


def _step4_rows() -> list[tuple[tuple[int, int], tuple[int, int], tuple[int, int], str]]:
    """Step-4 rows ``(fixed part, moving edge, (link a, link b), label)``; points 0..11 are
    ``S_0, E_0, ..., S_5, E_5``, 12 = L, 13 = R. Link a == b marks a pair static in link 3."""
    edge = {e: (e, (e + 1) % 12) for e in range(12)}
    name = {e: (f"S{e // 2}E{e // 2}" if e % 2 == 0 else f"E{e // 2}S{(e // 2 + 1) % 6}")
            for e in range(12)}
    rows = [(edge[e1], edge[e2], (la, lb), f"{name[e1]}-{name[e2]}")
            for e1, e2, la, lb in OFFSET_PAIRS.tolist() if 6 not in (e1, e2)]
    others = [e for e in range(12) if e != 6]
    for part, label, skip in (((6, 12), "S3L", (4, 5)), ((13, 7), "RE3", (7, 8))):
        rows += [(part, edge[e], (3, _edge_link(e)), f"{label}-{name[e]}")
                 for e in others if e not in skip]
    return rows + [((_MESH, _MESH), edge[e], (3, _edge_link(e)), f"P-{name[e]}") for e in others]


_THIN = _thin_rows()
_STEP4 = _step4_rows()
#: The rows of :data:`offsetting.OFFSET_PAIRS` kept (without the bar ``S_3E_3``, edge 6).
_BASE_PAIRS = OFFSET_PAIRS[~np.any(OFFSET_PAIRS[:, :2] == 6, axis=1)]
_IS_MESH = np.array([r[0][0] == _MESH for r in _STEP4])
_STATIC = np.array([r[2][0] == r[2][1] for r in _STEP4])


def _axes_of(pts: tuple[int, ...]) -> set[int]:
    """Axes whose offset digit moves 12-polyline points (S_i on A_{i-1}, E_i on A_i)."""
    return {((v // 2) - 1) % 6 if v % 2 == 0 else v // 2 for v in pts if 0 <= v < 12}


#: ``(rows, 6)``: which offset digits each step-4 row depends on (cache key mask).
_ROW_AXES = np.array([[a in _axes_of(f + m) for a in range(6)] for f, m, _, _ in _STEP4])


@dataclass(frozen=True)
class EndEffectorRealization:
    """Bars and pins as a :class:`realize.Realization` (its ``pairs`` omit the dropped bar
    ``S_3E_3``), the attached ``effector``, and the certificate of the end-effector rows:
    ``ee_labels``, ``ee_links`` ``(N, 2)``, ``ee_distance``/``ee_t`` ``(N,)`` (exact minima over
    the cycle; ``ee_exact`` False where P's bounding sphere already gives a certified lower
    bound), ``ee_required`` ``(N,)`` (2 rho for bars, ``ee_clearance`` for P)."""

    realization: Realization
    effector: EndEffector
    ee_labels: tuple[str, ...]
    ee_links: np.ndarray
    ee_distance: np.ndarray
    ee_t: np.ndarray
    ee_exact: np.ndarray
    ee_required: np.ndarray

    def end_link(self) -> np.ndarray:
        """End-link path ``(4, 3)`` at home: ``S_3, L, R, E_3``."""
        pts, v = self.realization.points, self.effector.vertices
        return np.stack([pts[6], v[self.effector.L], v[self.effector.R], pts[7]])


def thin_collides(joint_factors: np.ndarray, effector: EndEffector, polyline: np.ndarray
                  ) -> bool:
    """Thin check with the end-effector: does the linkage of the closed polyline ``(6, 3)``
    (end link routed ``V_2 L + P + R V_3``) collide anywhere on the cycle?"""
    jf = np.asarray(joint_factors, dtype=np.float64)
    v = np.asarray(polyline, dtype=np.float64)
    if jf.shape != (6, 8) or v.shape != (6, 3):
        raise RealizationError(f"need joint factors (6, 8) and a polyline (6, 3), got "
                               f"{jf.shape}, {v.shape}", "bad-parameters")
    mot = PairMotions(jf, {r[2] for r in _THIN})
    return bool(_segment_hits(mot, effector, v[None])[0]
                or _EffectorHits(mot, effector, v, np.zeros((6, 3)))(np.zeros((1, 6), int))[0])


def ee_segments(r: EndEffectorRealization) -> tuple[np.ndarray, np.ndarray]:
    """Home geometry of the certificate rows: fixed parts ``(N, 2, 3)`` in link 3 (NaN where
    the part is P) and the moving edges ``(N, 2, 3)`` (carried by ``ee_links[:, 1]``)."""
    pts = np.concatenate([r.realization.points, r.end_link()[1:3]])  # 12 = L, 13 = R
    rows = _STEP4[len(_BASE_PAIRS):]
    fixed = np.array([pts[list(f)] if f[0] != _MESH else np.full((2, 3), np.nan)
                      for f, _, _, _ in rows])
    return fixed, np.array([pts[list(m)] for _, m, _, _ in rows])


def effector_at(r: EndEffectorRealization, t: np.ndarray) -> np.ndarray:
    """Vertices of P ``(T, V, 3)`` at parameters ``t`` ``(T,)`` (base/world frame)."""
    pose = loops.link_poses(r.realization.joint_factors, t)[:, 3]
    return dq.transform_points(pose[:, None], r.effector.vertices[None])


def ee_to_dict(r: EndEffectorRealization) -> dict:
    """JSON-ready end-effector part of the result (``t`` null where the minimum is at home)."""
    e = r.effector
    return {
        "vertices": e.vertices.tolist(), "faces": e.faces.tolist(), "L": e.L, "R": e.R,
        "closed": e.closed, "end_link": r.end_link().tolist(),
        "pairs": [{"label": lab, "links": [int(a), int(b)], "min_distance": float(dist),
                   "t": None if np.isinf(t) else float(t), "exact": bool(ex),
                   "required": float(req)}
                  for lab, (a, b), dist, t, ex, req in zip(
                      r.ee_labels, r.ee_links, r.ee_distance, r.ee_t, r.ee_exact,
                      r.ee_required, strict=True)],
        "min_clearance": float(np.min(r.ee_distance - r.ee_required)),
    }


def _segment_hits(mot: PairMotions, ee: EndEffector, polys: np.ndarray) -> np.ndarray:
    """Mask ``(C,)``: a thin segment pair (bars of P's link included) of ``(C, 6, 3)`` collides.
    Low motion degrees first; only still-free candidates go on."""
    n = len(polys)
    pts = np.concatenate([polys, np.broadcast_to(ee.vertices[[ee.L, ee.R]], (n, 2, 3))], 1)
    rows = [r for r in _THIN if r[0][0] != _MESH]  # points: V_0..V_5, 6 = L, 7 = R
    hit = np.zeros(n, dtype=bool)
    for deg, pos, midx in mot.split([r[2] for r in rows]):
        alive = np.flatnonzero(~hit)
        if alive.size == 0:
            break
        fixed = pts[alive][:, [rows[p][0] for p in pos]].reshape(-1, 2, 3)
        moving = pts[alive][:, [rows[p][1] for p in pos]].reshape(-1, 2, 3)
        h, _ = pair_collisions(mot.groups[deg], np.tile(midx, alive.size), fixed, moving)
        hit[alive[h.reshape(alive.size, -1).any(axis=1)]] = True
    return hit


class _EffectorHits:
    """P against the thin segments of links 0, 1, 2, 4, 5 for one level k. Segment j depends
    only on the shift digits of its two axes, so each distinct segment (at most 9 per link) is
    checked once, lazily, and cached."""

    def __init__(self, mot: PairMotions, ee: EndEffector, v0: np.ndarray, step: np.ndarray):
        self.mot, self.ee = mot, ee
        rows = [r for r in _THIN if r[0][0] == _MESH]
        self.ends = np.array([r[1] for r in rows])  # (5, 2) vertex indices of each segment
        self.keys = [r[2] for r in rows]
        shifts = np.array([0.0, 1.0, -1.0])[:, None, None] * step  # digit -> shift (3, 6, 3)
        self.seg = np.stack([np.stack([v0[self.ends[:, 0]] + shifts[da][self.ends[:, 0]],
                                       v0[self.ends[:, 1]] + shifts[db][self.ends[:, 1]]], 1)
                             for da in range(3) for db in range(3)], 1)  # (5, 9, 2, 3)
        self.known = np.zeros((len(rows), 9), dtype=bool)
        self.hit = np.zeros((len(rows), 9), dtype=bool)

    def __call__(self, digits: np.ndarray) -> np.ndarray:
        """Mask ``(C,)`` for candidates with shift digits ``(C, 6)`` (0, +k, -k -> 0, 1, 2)."""
        code = 3 * digits[:, self.ends[:, 0]] + digits[:, self.ends[:, 1]]  # (C, 5)
        rows = np.broadcast_to(np.arange(len(self.keys)), code.shape)
        todo = np.unique(np.stack([rows[~self.known[rows, code]], code[~self.known[rows, code]]],
                                  1), axis=0)
        if len(todo):
            seg = self.seg[todo[:, 0], todo[:, 1]]
            hit = np.zeros(len(todo), dtype=bool)
            ee = self.ee
            for deg, pos, midx in self.mot.split([self.keys[r] for r in todo[:, 0]]):
                hit[pos] = mesh_segment_collisions(self.mot.groups[deg], midx, ee.vertices,
                                                   ee.faces, ee.edges, seg[pos])
            if ee.closed:  # a collision-free segment is wholly inside or wholly outside P
                hit |= inside_closed(ee.vertices, ee.faces, seg[:, 0])
            self.hit[todo[:, 0], todo[:, 1]] = hit
            self.known[todo[:, 0], todo[:, 1]] = True
        return self.hit[rows, code].any(axis=1)


class _Step4:
    """Step 4 with the end-effector for one thin polyline: values per (row, digit code)."""

    def __init__(self, lp: LoopMotions, mot: PairMotions, ee: EndEffector, v: np.ndarray,
                 d: float, rho: float, clearance: float):
        self.search = OffsetSearch(lp, v, d, rho)  # only its vertex table is used
        self.mot, self.ee = mot, ee
        n = len(_STEP4)
        self.clearance = clearance
        self.need = np.where(_IS_MESH, clearance, 2.0 * rho)
        self.value = np.full((n, 729), np.nan)  # upper bound (sampled) or final value
        self.t = np.full((n, 729), np.inf)
        self.final = np.zeros((n, 729), dtype=bool)
        self.exact = np.ones((n, 729), dtype=bool)

    def codes(self, seqs: np.ndarray) -> np.ndarray:
        """Cache columns ``(S, rows)``: each row's sequence with irrelevant digits zeroed."""
        return (DIGITS[seqs][:, None, :] * _ROW_AXES[None]) @ 3 ** np.arange(5, -1, -1)

    def _parts(self, rows: np.ndarray, codes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fixed and moving segments ``(K, 2, 3)`` (fixed is garbage for P rows)."""
        uniq, inv = np.unique(codes, return_inverse=True)
        lr = self.ee.vertices[[self.ee.L, self.ee.R]]
        pts = np.stack([np.concatenate([self.search.points(int(c)), lr]) for c in uniq])[inv]
        f = np.array([_STEP4[r][0] for r in rows])
        m = np.array([_STEP4[r][1] for r in rows])
        k = np.arange(len(rows))[:, None]
        return pts[k, np.where(f < 0, 0, f)], pts[k, m]

    def _sample(self, codes: np.ndarray) -> None:
        """Upper bounds (true distances at 48 times) of the moving segment rows."""
        rows = np.broadcast_to(np.arange(len(_STEP4)), codes.shape)
        todo = np.isnan(self.value[rows, codes])
        rows, cols = _unique_items(rows[todo], codes[todo], ~_IS_MESH & ~_STATIC)
        if rows.size == 0:
            return
        fixed, moving = self._parts(rows, cols)
        for deg, pos, midx in self.mot.split([_STEP4[r][2] for r in rows]):
            moved = np.einsum("ktab,kvb->ktva", self.mot.rot[deg][midx], moving[pos]) + \
                self.mot.trans[deg][midx][:, :, None]
            dist = segment_distance(fixed[pos, None, 0], fixed[pos, None, 1], moved[..., 0, :],
                                    moved[..., 1, :])
            self.value[rows[pos], cols[pos]] = dist.min(axis=1)

    def _finish(self, codes: np.ndarray) -> None:
        rows = np.broadcast_to(np.arange(len(_STEP4)), codes.shape)
        todo = ~self.final[rows, codes]
        rows, cols = _unique_items(rows[todo], codes[todo], np.ones(len(_STEP4), dtype=bool))
        if rows.size == 0:
            return
        fixed, moving = self._parts(rows, cols)
        ee = self.ee
        static = _STATIC[rows]
        dist, t, exact = np.zeros(len(rows)), np.full(len(rows), np.inf), np.ones(len(rows), bool)
        seg_static = static & ~_IS_MESH[rows]
        dist[seg_static] = segment_distance(fixed[seg_static, 0], fixed[seg_static, 1],
                                            moving[seg_static, 0], moving[seg_static, 1])
        mesh_static = static & _IS_MESH[rows]
        dist[mesh_static] = segment_triangle_distance(moving[mesh_static, None],
                                                      ee.vertices[ee.faces][None]).min(axis=1)
        moving_rows = np.flatnonzero(~static)
        for deg, pos, midx in self.mot.split([_STEP4[r][2] for r in rows[moving_rows]]):
            at, md = moving_rows[pos], self.mot.groups[deg]
            mesh = _IS_MESH[rows[at]]
            if np.any(~mesh):
                s = at[~mesh]
                dist[s], t[s] = min_distance_batch(md, midx[~mesh], fixed[s], moving[s])
            if np.any(mesh):
                s = at[mesh]
                dist[s], t[s], exact[s] = mesh_segment_clearance(
                    md, midx[mesh], ee.vertices, ee.faces, ee.edges, moving[s], self.clearance)
        if ee.closed:  # an edge inside a closed P never touches its surface: refuse it
            mesh = np.flatnonzero(_IS_MESH[rows])
            dist[mesh[inside_closed(ee.vertices, ee.faces, moving[mesh, 0])]] = 0.0
        self.value[rows, cols], self.t[rows, cols], self.exact[rows, cols] = dist, t, exact
        self.final[rows, cols] = True

    def _ok(self, codes: np.ndarray) -> np.ndarray:
        val = self.value[np.arange(len(_STEP4)), codes]
        return np.all(np.isnan(val) | (val >= self.need), axis=1)

    def run(self, order: np.ndarray) -> tuple[int | None, int]:
        """First sequence of ``order`` clearing every row, and how many were examined
        (same windows as :meth:`offsetting.OffsetSearch.run`)."""
        for chunk in (order[:1], order[1:2], order[2:]):
            codes = self.codes(chunk)
            self._sample(codes)
            start, window = 0, 1
            while True:
                passing = np.flatnonzero(self._ok(codes))
                batch = passing[passing >= start][:window]
                if batch.size == 0:
                    break
                self._finish(codes[batch])
                ok = self._ok(codes[batch])
                if ok.any():
                    seq = int(chunk[batch[np.argmax(ok)]])
                    return seq, int(np.flatnonzero(order == seq)[0]) + 1
                start, window = batch[-1] + 1, 2 * window
        return None, len(order)


def _unique_items(rows: np.ndarray, cols: np.ndarray, keep: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Distinct (row, code) items among those whose row is kept."""
    sel = keep[rows]
    items = np.unique(np.stack([rows[sel], cols[sel]], axis=1), axis=0)
    return items[:, 0], items[:, 1]


def _bar_of(part: tuple[int, int]) -> int:
    """Link whose bar ``part`` is (``S_3L``, ``RE_3`` count for link 3), -1 for pins and P."""
    if part in ((6, 12), (13, 7)):
        return 3
    return part[0] // 2 if part[0] >= 0 and part[0] % 2 == 0 and part[1] == part[0] + 1 else -1


_ROW_BARS = np.array([(_bar_of(f), _bar_of(m)) for f, m, _, _ in _STEP4])  # (rows, 2)


def _design_space_radii(dist: np.ndarray, rho: float) -> np.ndarray:
    """Sec. 5.2 radii ``(6,)`` over all rows: bar vs bar splits D evenly, a bar keeps
    ``D - rho`` from a pin and ``D`` from P."""
    radii = np.full(6, np.inf)
    for me, other in ((0, 1), (1, 0)):
        bar = _ROW_BARS[:, me]
        cap = np.where(_ROW_BARS[:, other] >= 0, dist / 2.0, np.where(_IS_MESH, dist, dist - rho))
        np.minimum.at(radii, bar[bar >= 0], cap[bar >= 0])
    return radii


def realize_with_effector(
    joint_factors: np.ndarray,
    effector: EndEffector,
    *,
    p: float = 10.0,
    rho: float | None = None,
    d: float | None = None,
    d_fraction: float = 0.01,
    rho_fraction: float = 0.25,
    fixed: dict[int, float] | None = None,
    max_k: int = 50,
    ee_clearance: float | None = None,
) -> EndEffectorRealization:
    """Collision-free realization of ``joint_factors`` ``(6, 8)`` whose end link carries
    ``effector`` (from :func:`endeffector.attach`). Parameters as :func:`realize.realize`
    (``fixed`` may hold ``V_2``/``V_3`` as well); ``ee_clearance`` (default rho) is the least
    distance between P and any bar or pin centre line. ``l`` is the initial polyline's length
    with the end link routed ``V_2 L R V_3``. Raises :class:`RealizationError`."""
    jf = np.asarray(joint_factors, dtype=np.float64)
    if fixed is not None and len(fixed) >= 6:
        raise RealizationError("at most five vertices can be fixed (the search shifts the "
                               f"free ones), got {len(fixed)}", "bad-parameters")
    anchors = effector.vertices[[effector.L, effector.R]]
    v0, u = initial_polyline(jf, anchors, fixed)
    length = float(ee_length(v0, anchors))
    d = d_fraction * length if d is None else d
    rho = rho_fraction * d if rho is None else rho
    check_params(p, rho, d, max_k)
    clearance = rho if ee_clearance is None else ee_clearance
    if not (np.isfinite(clearance) and clearance >= 0):
        raise RealizationError(f"ee_clearance must be >= 0, got {clearance!r}", "bad-parameters")
    lp = LoopMotions(jf)
    mot = PairMotions(jf, {r[2] for r in _THIN} | {r[2] for r in _STEP4})
    free = np.array([i not in (fixed or {}) for i in range(6)])
    patterns = DIGITS[np.all(DIGITS[:, ~free] == 0, axis=1)][1:]
    tau_unit = np.where(patterns == 2, -1, patterns)
    checks = steps_back = tried = 0
    for k in range(max_k + 1):
        tau = np.zeros((1, 6), int) if k == 0 else k * tau_unit
        polys = v0 + (tau * length / p)[..., None] * u
        order = np.argsort(ee_length(polys, anchors), kind="stable")
        tau, polys = tau[order], polys[order]
        digits = np.where(tau > 0, 1, np.where(tau < 0, 2, 0))
        hits = _EffectorHits(mot, effector, v0, k * length / p * u)
        for pos in _free(mot, effector, polys, digits, hits):
            step = _Step4(lp, mot, effector, polys[pos], d, rho, clearance)
            seq, n_seq = step.run(sequence_order(np.sign(tau[pos])))
            tried += n_seq
            if seq is None:
                steps_back += 1
                continue
            codes = step.codes(np.array([seq]))[0]
            rows = np.arange(len(_STEP4))
            dist, t = step.value[rows, codes], step.t[rows, codes]
            points = step.search.points(seq)
            base = rows < len(_BASE_PAIRS)
            stats = {"k": k, "collision_checks": checks + len(polys), "steps_back": steps_back,
                     "min_distance_computations": tried, "offset_rank": min(n_seq - 1, 2),
                     "collision_checks_sequential": checks + pos + 1,
                     "length_ratio": float(ee_length(points, anchors, offset=True)) / length}
            real = Realization(jf, points, float(rho), float(d), length, float(p), tau[pos],
                               OFFSET_WAYS[DIGITS[seq]], v0, polys[pos], _BASE_PAIRS,
                               dist[base], t[base], _design_space_radii(dist, rho), stats)
            ee = ~base
            return EndEffectorRealization(
                real, effector, tuple(r[3] for r, e in zip(_STEP4, ee, strict=True) if e),
                np.array([r[2] for r in _STEP4])[ee], dist[ee], t[ee],
                step.exact[rows, codes][ee], step.need[ee])
        checks += len(polys)
    raise RealizationError(
        f"no collision-free realization with the end-effector for k <= {max_k} (p = {p}, "
        f"d = {d:.4g}, rho = {rho:.4g}): {checks} thin polylines checked, {steps_back} "
        "collision-free ones failed the clearances; raise max_k, shrink or move P, or choose "
        "other L and R", "cap-reached")


def _free(mot: PairMotions, ee: EndEffector, polys: np.ndarray, digits: np.ndarray,
          effector_hits: _EffectorHits):
    """Positions of the collision-free thin polylines ``(C, 6, 3)`` (shift digits ``(C, 6)``),
    in order, checked in chunks: segment pairs first, P for the survivors."""
    start, size = 0, 16
    while start < len(polys):
        stop = min(start + size, len(polys))
        todo = np.flatnonzero(~_segment_hits(mot, ee, polys[start:stop]))
        todo = todo[~effector_hits(digits[start:stop][todo])]
        for pos in todo:
            yield start + int(pos)
        start, size = stop, size * 2
