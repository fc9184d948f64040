"""Realization with an end-effector (paper Sec. 5.1 "End-effector integration", Fig. 7, 9): the
search.

The end link 3 becomes ``S_3 L + P + R E_3``: the polyhedron P (at home, base/world frame)
and two bars from ``S_3`` (on ``A_2``) to the vertex L of P and from the vertex R to ``E_3``
(on ``A_3``). L and R never move; the initial polyline is eq. 11 with the end link routed
``V_2 L R V_3`` (:func:`endeffector.initial_polyline`), and ``V_2``, ``V_3`` shift like the
other vertices unless fixed (Fig. 9 fixes them too). The search of :func:`realize.realize`
(:class:`realize.Search`) runs unchanged (same candidates, order and offset sequences) with
the extra exact checks of :mod:`ee_certificate` (the pair rows and the result), as the hooks
of :class:`EffectorSearch`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from paraloop_core.errors import RealizationError
from paraloop_core.realization import verify
from paraloop_core.realization.certified import Realization
from paraloop_core.realization.clearance import PairMotions, min_distance_batch, segment_distance
from paraloop_core.realization.collision import pair_collisions
from paraloop_core.realization.ee_certificate import (
    BASE_PAIRS,
    IS_MESH,
    IS_STATIC,
    MESH,
    STEP4_ROWS,
    THIN_ROWS,
    EndEffectorRealization,
    design_space_radii,
)
from paraloop_core.realization.endeffector import EndEffector, ee_length, initial_polyline
from paraloop_core.realization.facecollide import (
    inside_closed,
    mesh_segment_clearance,
    mesh_segment_collisions,
    segment_triangle_distance,
)
from paraloop_core.realization.offsetting import (
    DIGITS,
    OFFSET_WAYS,
    V_AXIS,
    LoopMotions,
    OffsetSearch,
)
from paraloop_core.realization.realize import VERIFY_TOL, Search

#: Consecutive-bar pairs without the replaced end-link bar ``S_3E_3`` (edge 6).
_EE_JOINT_PAIRS = verify.JOINT_PAIRS[~np.any(verify.JOINT_PAIRS[:, :2] == 6, axis=1)]


def _axes_of(pts: tuple[int, ...]) -> set[int]:
    """Axes whose offset digit moves 12-polyline points (S_i on A_{i-1}, E_i on A_i)."""
    return {int(V_AXIS[v]) for v in pts if 0 <= v < 12}


#: ``(rows, 6)``: which offset digits each step-4 row depends on (cache key mask).
_ROW_AXES = np.array([[a in _axes_of(f + m) for a in range(6)] for f, m, _, _ in STEP4_ROWS])


def thin_collides(joint_factors: np.ndarray, effector: EndEffector, polyline: np.ndarray
                  ) -> bool:
    """Thin check with the end-effector: does the linkage of the closed polyline ``(6, 3)``
    (end link routed ``V_2 L + P + R V_3``) collide anywhere on the cycle?"""
    jf = np.asarray(joint_factors, dtype=np.float64)
    v = np.asarray(polyline, dtype=np.float64)
    if jf.shape != (6, 8) or v.shape != (6, 3):
        raise RealizationError(f"need joint factors (6, 8) and a polyline (6, 3), got "
                               f"{jf.shape}, {v.shape}", "bad-parameters")
    mot = PairMotions(jf, {r[2] for r in THIN_ROWS})
    return bool(_segment_hits(mot, effector, v[None])[0]
                or _EffectorHits(mot, effector, v, np.zeros((6, 3)))(np.zeros((1, 6), int))[0])


def _segment_hits(mot: PairMotions, ee: EndEffector, polys: np.ndarray) -> np.ndarray:
    """Mask ``(C,)``: a thin segment pair (bars of P's link included) of ``(C, 6, 3)`` collides.
    Low motion degrees first; only still-free candidates go on."""
    n = len(polys)
    pts = np.concatenate([polys, np.broadcast_to(ee.vertices[[ee.L, ee.R]], (n, 2, 3))], 1)
    rows = [r for r in THIN_ROWS if r[0][0] != MESH]  # points: V_0..V_5, 6 = L, 7 = R
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
        rows = [r for r in THIN_ROWS if r[0][0] == MESH]
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
        n = len(STEP4_ROWS)
        self.clearance = clearance
        self.need = np.where(IS_MESH, clearance, 2.0 * rho)
        self.value = np.full((n, 729), np.nan)  # upper bound (sampled) or final value
        self.t = np.full((n, 729), np.inf)
        self.final = np.zeros((n, 729), dtype=bool)
        self.exact = np.ones((n, 729), dtype=bool)

    def points(self, seq: int) -> np.ndarray:
        """Vertices ``(12, 3)`` of offset sequence ``seq`` (search units)."""
        return self.search.points(seq)

    def codes(self, seqs: np.ndarray) -> np.ndarray:
        """Cache columns ``(S, rows)``: each row's sequence with irrelevant digits zeroed."""
        return (DIGITS[seqs][:, None, :] * _ROW_AXES[None]) @ 3 ** np.arange(5, -1, -1)

    def _parts(self, rows: np.ndarray, codes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Fixed and moving segments ``(K, 2, 3)`` (fixed is garbage for P rows)."""
        uniq, inv = np.unique(codes, return_inverse=True)
        lr = self.ee.vertices[[self.ee.L, self.ee.R]]
        pts = np.stack([np.concatenate([self.search.points(int(c)), lr]) for c in uniq])[inv]
        f = np.array([STEP4_ROWS[r][0] for r in rows])
        m = np.array([STEP4_ROWS[r][1] for r in rows])
        k = np.arange(len(rows))[:, None]
        return pts[k, np.where(f < 0, 0, f)], pts[k, m]

    def _sample(self, codes: np.ndarray) -> None:
        """Upper bounds (true distances at 48 times) of the moving segment rows."""
        rows = np.broadcast_to(np.arange(len(STEP4_ROWS)), codes.shape)
        todo = np.isnan(self.value[rows, codes])
        rows, cols = _unique_items(rows[todo], codes[todo], ~IS_MESH & ~IS_STATIC)
        if rows.size == 0:
            return
        fixed, moving = self._parts(rows, cols)
        for deg, pos, midx in self.mot.split([STEP4_ROWS[r][2] for r in rows]):
            moved = np.einsum("ktab,kvb->ktva", self.mot.rot[deg][midx], moving[pos]) + \
                self.mot.trans[deg][midx][:, :, None]
            dist = segment_distance(fixed[pos, None, 0], fixed[pos, None, 1], moved[..., 0, :],
                                    moved[..., 1, :])
            self.value[rows[pos], cols[pos]] = dist.min(axis=1)

    def _finish(self, codes: np.ndarray) -> None:
        rows = np.broadcast_to(np.arange(len(STEP4_ROWS)), codes.shape)
        todo = ~self.final[rows, codes]
        rows, cols = _unique_items(rows[todo], codes[todo], np.ones(len(STEP4_ROWS), dtype=bool))
        if rows.size == 0:
            return
        fixed, moving = self._parts(rows, cols)
        ee = self.ee
        static = IS_STATIC[rows]
        dist, t, exact = np.zeros(len(rows)), np.full(len(rows), np.inf), np.ones(len(rows), bool)
        seg_static = static & ~IS_MESH[rows]
        dist[seg_static] = segment_distance(fixed[seg_static, 0], fixed[seg_static, 1],
                                            moving[seg_static, 0], moving[seg_static, 1])
        mesh_static = static & IS_MESH[rows]
        dist[mesh_static] = segment_triangle_distance(moving[mesh_static, None],
                                                      ee.vertices[ee.faces][None]).min(axis=1)
        moving_rows = np.flatnonzero(~static)
        for deg, pos, midx in self.mot.split([STEP4_ROWS[r][2] for r in rows[moving_rows]]):
            at, md = moving_rows[pos], self.mot.groups[deg]
            mesh = IS_MESH[rows[at]]
            if np.any(~mesh):
                s = at[~mesh]
                dist[s], t[s] = min_distance_batch(md, midx[~mesh], fixed[s], moving[s])
            if np.any(mesh):
                s = at[mesh]
                dist[s], t[s], exact[s] = mesh_segment_clearance(
                    md, midx[mesh], ee.vertices, ee.faces, ee.edges, moving[s], self.clearance)
        if ee.closed:  # an edge inside a closed P never touches its surface: refuse it
            mesh = np.flatnonzero(IS_MESH[rows])
            dist[mesh[inside_closed(ee.vertices, ee.faces, moving[mesh, 0])]] = 0.0
        self.value[rows, cols], self.t[rows, cols], self.exact[rows, cols] = dist, t, exact
        self.final[rows, cols] = True

    def _ok(self, codes: np.ndarray) -> np.ndarray:
        val = self.value[np.arange(len(STEP4_ROWS)), codes]
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


class EffectorSearch(Search):
    """:class:`realize.Search` with the end-effector (its :meth:`run_hint` warm-starts, as
    the base class's): the initial polyline routed through L
    and R, thin checks of the segment pairs then of P, step 4 by :class:`_Step4`."""

    cap_message = ("no collision-free realization with the end-effector for k <= {max_k} "
                   "(p = {p}, d = {d:.4g}, rho = {rho:.4g}): {checks} thin polylines checked, "
                   "{steps_back} collision-free ones failed the clearances; raise max_k, "
                   "shrink or move P, or choose other L and R")

    def __init__(self, joint_factors: np.ndarray, fixed: dict[int, float] | None,
                 effector: EndEffector, ee_clearance: float | None, in_unit: float = 1.0):
        super().__init__(joint_factors, fixed, in_unit)
        self.ee_design = effector
        self.ee = replace(effector, vertices=effector.vertices / self.unit)
        self.ee_clearance = None if ee_clearance is None else ee_clearance / self.unit
        self.anchors = self.ee.vertices[[effector.L, effector.R]]

    def initial(self) -> tuple[np.ndarray, float]:
        v0, _ = initial_polyline(self.jf, self.anchors, self.fixed)
        return v0, float(ee_length(v0, self.anchors))

    def start(self) -> None:
        self.clearance = self.rho if self.ee_clearance is None else self.ee_clearance
        if not (np.isfinite(self.clearance) and self.clearance >= 0):
            raise RealizationError(f"ee_clearance must be >= 0, got "
                                   f"{self.clearance * self.unit!r}", "bad-parameters",
                                   "clearance")
        super().start()
        self.mot = PairMotions(self.jf, {r[2] for r in THIN_ROWS} | {r[2] for r in STEP4_ROWS})

    def lengths(self, polys: np.ndarray) -> np.ndarray:
        return ee_length(polys, self.anchors)

    def colliding(self, k: int, tau: np.ndarray, polys: np.ndarray
                  ) -> Callable[[int, int], np.ndarray]:
        """Segment pairs first, P (cached per level) for the survivors."""
        digits = np.where(tau > 0, 1, np.where(tau < 0, 2, 0))
        effector_hits = _EffectorHits(self.mot, self.ee, self.v0, k * self.length / self.p
                                      * self.lp.u)

        def chunk(start: int, stop: int) -> np.ndarray:
            hit = _segment_hits(self.mot, self.ee, polys[start:stop])
            todo = np.flatnonzero(~hit)
            hit[todo[effector_hits(digits[start:stop][todo])]] = True
            return hit
        return chunk

    def step4(self, v: np.ndarray) -> _Step4:
        return _Step4(self.lp, self.mot, self.ee, v, self.d, self.rho, self.clearance)

    def verify(self, step: _Step4, seq: int) -> object | None:
        """Sound bounds of the bar and pin pairs (:mod:`verify`); the pairs with P keep the
        exact edge-face certificate (:mod:`facecollide`)."""
        codes = step.codes(np.array([seq]))[0]
        rows = np.arange(len(STEP4_ROWS))
        t = step.t[rows, codes][:len(BASE_PAIRS)]  # base rows first
        points = step.search.points(seq)
        proof = self.bounds(points, BASE_PAIRS, t)
        if proof is None:
            return None
        # P's rows hold for either reading of the loop too (:meth:`reading_gap`)
        ee = rows >= len(BASE_PAIRS)
        gap = self.reading_gap(np.concatenate([points, self.ee.vertices]))
        if (step.value[rows, codes][ee] - gap < step.need[ee]).any():
            return None
        return proof

    def result(self, step: _Step4, seq: int, tau: np.ndarray, v: np.ndarray, stats: dict,
               proof: object) -> EndEffectorRealization:
        pairs, gap = proof
        codes = step.codes(np.array([seq]))[0]
        rows = np.arange(len(STEP4_ROWS))
        dist, t = step.value[rows, codes], step.t[rows, codes]
        points = step.search.points(seq)
        base = rows < len(BASE_PAIRS)
        dist[base], t[base] = pairs.upper, pairs.t
        lower = dist.copy()
        lower[base] = pairs.lower
        stats["length_ratio"] = float(ee_length(points, self.anchors, offset=True)) / self.length
        real = Realization(self.jf, points, float(self.rho), float(self.d), self.length,
                           float(self.p), tau, OFFSET_WAYS[DIGITS[seq]], self.v0, v, BASE_PAIRS,
                           dist[base], t[base], design_space_radii(lower, self.rho), stats,
                           pairs.lower, _EE_JOINT_PAIRS, VERIFY_TOL * self.length, gap)
        ee = ~base
        u = self.unit
        return EndEffectorRealization(
            real.scaled(u, self.jf_design), self.ee_design,
            tuple(r[3] for r, e in zip(STEP4_ROWS, ee, strict=True) if e),
            np.array([r[2] for r in STEP4_ROWS])[ee], dist[ee] * u, t[ee],
            step.exact[rows, codes][ee], step.need[ee] * u)


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
    budget: int | None = None,
    in_unit: float = 1.0,
    check: Callable[[], None] | None = None,
) -> EndEffectorRealization:
    """Collision-free realization of ``joint_factors`` ``(6, 8)`` whose end link carries
    ``effector`` (from :func:`endeffector.attach`). Parameters as :func:`realize.realize`
    (``fixed`` may hold ``V_2``/``V_3`` as well); ``ee_clearance`` (default rho) is the least
    distance between P and any bar or pin centre line. ``l`` is the initial polyline's length
    with the end link routed ``V_2 L R V_3``; ``in_unit``, ``check`` as there. Raises
    :class:`RealizationError`."""
    search = EffectorSearch(joint_factors, fixed, effector, ee_clearance, in_unit)
    return search.run(p=p, rho=rho, d=d, d_fraction=d_fraction, rho_fraction=rho_fraction,
                      max_k=max_k, budget=budget, check=check)

