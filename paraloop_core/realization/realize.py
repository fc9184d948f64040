"""Collision-free realization of a 6R loop (paper Sec. 5.1 steps 1-4, Sec. 5.2 design spaces).

Step 1 (:mod:`polyline`): shortest closed polyline ``V_0..V_5`` on the axes (home, base frame).
Step 2/3 (:mod:`collision`): shift vertices by ``tau l / p``, ``tau in {-k, 0, +k}``; candidates of
one k are ordered by thin-polyline length (shortest first, ties by the base-3 index of the shift
digits ``(0, +k, -k)``, axis 0 most significant) and checked in batched chunks in that order.
Step 4 (:mod:`offsetting`): offsets, thick bars, the 42 exact pair minima (the certificate).
Sec. 5.2: cylindrical design spaces from the certificate.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import Any

import numpy as np

from paraloop_core.algebra import dq
from paraloop_core.errors import RealizationError
from paraloop_core.realization import closure, verify
from paraloop_core.realization.certified import Realization, design_space_radii
from paraloop_core.realization.collision import colliding_polylines
from paraloop_core.realization.offsetting import (
    DIGITS,
    OFFSET_PAIRS,
    OFFSET_WAYS,
    LoopMotions,
    OffsetSearch,
    sequence_order,
)
from paraloop_core.realization.polyline import polyline_length, shortest_polyline

#: Wanted gap between reported and proven pair minima, as a fraction of the polyline length l
#: (plus :data:`verify.RELATIVE` of the pair's own distance).
VERIFY_TOL = 1e-6
#: Precision (per polyline length) of the accepted polyline's lower bounds, the room the
#: design spaces and the printed parts' sizing use: 0.2 % of the size is below what a print
#: resolves, and costs a fraction of full precision (a few ms per realization).
ROOM_TOL = 2e-3
#: Work units of one step-4 offset sequence examined and of one certificate cell, in thin
#: polyline checks (the unit: about 0.3 ms on one core); measured, so that a budget is
#: roughly a time, the same on every machine and at every scale.
SEQUENCE_WORK = 6
CELLS_PER_WORK = 20


def _free_candidates(n: int, colliding: Callable[[int, int], np.ndarray]) -> Iterator[int]:
    """Positions of the collision-free ones of ``n`` ordered candidates, checked in growing
    chunks: ``colliding(start, stop)`` is the collision mask of candidates ``start:stop``."""
    start, size = 0, 16
    while start < n:
        stop = min(start + size, n)
        for pos in np.flatnonzero(~colliding(start, stop)):
            yield start + int(pos)
        start, size = stop, size * 2


def unit_length(joint_factors: np.ndarray) -> float:
    """Length unit of the search of a loop ``(6, 8)``: the largest distance of a joint axis
    from the origin (1 when every axis passes through it: a spherical loop, refused later).
    The search runs in this unit, so its thresholds and its answer do not depend on the
    design's unit."""
    jf = np.asarray(joint_factors, dtype=np.float64)
    dist = np.linalg.norm(jf[:, 5:8], axis=-1) / np.linalg.norm(jf[:, 1:4], axis=-1)
    unit = float(dist.max())
    return unit if np.isfinite(unit) and unit > 0 else 1.0


def check_params(p: float, rho: float, d: float, max_k: int) -> None:
    """Refuse impossible search parameters: RealizationError (``bad-parameters``) whose
    ``param`` names the first bad one (``p``, ``d``, ``rho``, ``max_k``) and its range."""
    bad = [("p", not (np.isfinite(p) and p > 0), f"p must be positive, got {p!r}"),
           ("d", not (np.isfinite(d) and d > 0), f"d must be positive, got {d!r}"),
           ("rho", not (np.isfinite(rho) and rho > 0), f"rho must be positive, got {rho!r}"),
           ("rho", not d >= 2.0 * rho,
            f"the separation d must be at least 2 rho: rho must be in (0, d / 2 = {d / 2:.4g}] "
            f"for d = {d:.4g}, got rho = {rho:.4g}"),
           ("max_k", not (isinstance(max_k, (int, np.integer)) and max_k >= 1),
            f"max_k must be an integer >= 1, got {max_k!r}")]
    for param, failed, message in bad:
        if failed:
            raise RealizationError(f"bad realization parameters: {message}", "bad-parameters",
                                   param)


class Search:
    """The search of Sec. 5.1 for one loop, for the bars alone: :meth:`run` drives the shift
    levels, candidate order, thin checks, step 4 and the steps back to step 3; the hooks
    (:meth:`initial`, :meth:`start`, :meth:`lengths`, :meth:`colliding`, :meth:`step4`,
    :meth:`result`, :attr:`cap_message`) are what :mod:`realize_ee` overrides for an
    end-effector. Lengths inside are in :func:`unit_length` (``self.unit`` design units):
    ``self.jf`` and every hook work in it; :meth:`result` answers in design units."""

    #: ``cap-reached`` message; ``str.format`` fields max_k, p, d, rho, checks, steps_back.
    cap_message = ("no collision-free realization with k <= {max_k} (p = {p}, d = {d:.4g}, "
                   "rho = {rho:.4g}): {checks} thin polylines checked, {steps_back} "
                   "collision-free ones failed the 2 rho clearance; raise max_k, lower rho/d "
                   "or fix fewer vertices")

    def __init__(self, joint_factors: np.ndarray, fixed: dict[int, float] | None,
                 in_unit: float = 1.0):
        if fixed is not None and len(fixed) >= 6:
            raise RealizationError("at most five vertices can be fixed (the search shifts the "
                                   f"free ones), got {len(fixed)}", "bad-parameters", "fixed")
        jf = np.asarray(joint_factors, dtype=np.float64)
        own = unit_length(jf)
        # the search unit from the given numbers alone: factors with the same bits in any
        # ``in_unit`` (the pipeline's) give the same search, only its answer scales
        self.unit = own * in_unit
        self.jf = dq.scale_lengths(jf, 1.0 / own)
        self.jf_design = jf if in_unit == 1.0 else dq.scale_lengths(jf, in_unit)
        self.fixed = None if fixed is None else {i: v / self.unit for i, v in fixed.items()}
        self.cells = 0
        self._gap: tuple[float, float] | None = None  # closure.reading_gap, once needed

    def initial(self) -> tuple[np.ndarray, float]:
        """Step 1: the initial polyline ``(6, 3)`` and its length l."""
        _, v0 = shortest_polyline(self.jf, self.fixed)
        length = float(polyline_length(v0))
        if not length > 1e-12 * (1.0 + np.abs(v0).max()):
            raise RealizationError("the shortest polyline has zero length (all axes meet in "
                                   "one point): the loop is spherical, not realizable by bars",
                                   "singular-loop")
        return v0, length

    def start(self) -> None:
        """Per-loop data, once the parameters (``self.d``, ``self.rho``, ...) are checked."""
        self.lp = LoopMotions(self.jf)

    def lengths(self, polys: np.ndarray) -> np.ndarray:
        """Lengths ``(C,)`` ordering the candidates ``(C, 6, 3)`` of a level."""
        return polyline_length(polys)

    def colliding(self, k: int, tau: np.ndarray, polys: np.ndarray
                  ) -> Callable[[int, int], np.ndarray]:
        """Thin check of level k's ordered candidates ``(C, 6, 3)`` (shifts ``(C, 6)``): the
        mask of candidates ``start:stop`` (for :func:`_free_candidates`)."""
        return lambda start, stop: colliding_polylines(self.lp.thin, polys[start:stop])

    def step4(self, v: np.ndarray) -> OffsetSearch:
        """Step 4 for the thin polyline ``v`` ``(6, 3)``: ``run(order) -> (seq, examined)``."""
        return OffsetSearch(self.lp, v, self.d, self.rho)

    def verify(self, step: OffsetSearch, seq: int) -> object | None:
        """Sound bounds (:mod:`verify`) of the pairs of sequence ``seq``, or None when some
        pair cannot be proven >= 2 rho (the exact check missed a minimum or is unsure)."""
        points = step.points(seq)
        _, t = step.certificate(seq)
        return self.bounds(points, OFFSET_PAIRS, t)

    def reading_gap(self, points: np.ndarray) -> float:
        """Proven bound (search units) of how far any two float64 readings of the loop (one
        way round or the other; this loop or the reported one in design units) place a point
        of a link carrying ``points`` ``(N, 3)`` over the cycle (:mod:`closure`)."""
        if self._gap is None:
            self._gap = closure.reading_gap(self.jf)
        rot, shift = self._gap
        direction = np.linalg.norm(self.jf[:, 1:4], axis=1)
        # the readings differ by a conjugate of the loop product: the point is carried by at
        # most six rotations, each about an axis within ``axes`` of the origin, first
        axes = np.linalg.norm(self.jf[:, 5:8], axis=1) / direction
        radius = float(np.linalg.norm(points, axis=-1).max()) + 4.0 * float(axes.sum())
        # the reported loop is this one rescaled: each factor's dual part rounded (<= 2^-51 of
        # it, primal parts untouched), which moves a chain's translation by at most
        # 2 |delta d_m| / |primal of t - h_m| <= 2 |delta d_m| / |vec h_m|, twice (both loops)
        dual = np.linalg.norm(self.jf[:, 4:], axis=1)
        rescaled = 4.0 * 2.0**-51 * float((dual / direction).sum())
        return rot * radius + shift + rescaled

    def bounds(self, points: np.ndarray, pairs: np.ndarray, t: np.ndarray) -> tuple | None:
        """:meth:`verify` of the 12-vertex polyline ``points`` with its certified ``pairs``
        and exact minima ``t``; counts the cells. The lower bounds returned hold for either
        reading of the loop (:meth:`reading_gap` off)."""
        gap = self.reading_gap(points)
        need = 2.0 * self.rho + gap
        bounds = verify.polyline_bounds(self.jf, points, pairs, VERIFY_TOL * self.length, t,
                                        need=need)
        self.cells += int(bounds.cells.sum())
        if bounds.lower.min() < need:
            return None
        # proven clear: the search stopped refining each pair at twice what it needs, but the
        # design spaces and the printed parts' sizing use these bounds as the room between
        # the links, so the accepted polyline's pairs are refined to full precision (both
        # bounds are sound lower bounds: the larger one holds)
        tight = verify.polyline_bounds(self.jf, points, pairs, ROOM_TOL * self.length, t)
        self.cells += int(tight.cells.sum())
        lower = np.maximum(bounds.lower, tight.lower)
        nearer = tight.upper < bounds.upper  # both attained: the smaller is nearer the minimum
        return replace(bounds, lower=lower - gap, upper=np.where(nearer, tight.upper,
                                                                 bounds.upper),
                       t=np.where(nearer, tight.t, bounds.t)), gap

    def result(self, step: OffsetSearch, seq: int, tau: np.ndarray, v: np.ndarray,
               stats: dict, proof: object) -> Realization:
        """The realization by offset sequence ``seq`` of ``step`` with the bounds ``proof`` of
        :meth:`verify`; ``stats`` lacks the ``length_ratio``."""
        pairs, gap = proof
        points = step.points(seq)
        stats["length_ratio"] = float(polyline_length(points)) / self.length
        dist = pairs.upper
        return Realization(self.jf, points, float(self.rho), float(self.d), self.length,
                           float(self.p), tau, OFFSET_WAYS[DIGITS[seq]], self.v0, v,
                           OFFSET_PAIRS, dist, pairs.t, design_space_radii(pairs.lower, self.rho),
                           stats, pairs.lower, verify.JOINT_PAIRS,
                           VERIFY_TOL * self.length, gap).scaled(self.unit, self.jf_design)

    def run(self, *, p: float, rho: float | None, d: float | None, d_fraction: float,
            rho_fraction: float, max_k: int, budget: int | None = None, certify: bool = True,
            check: Callable[[], None] | None = None):
        """Parameters as :func:`realize`; the :meth:`result` of the first success.

        ``budget``: work units (:meth:`work`) after which the search stops with reason
        ``budget`` (checked between candidates): deterministic, unlike a wall-clock limit.
        ``check()`` is called there too; it may raise to stop the search (the studio's cancel).
        Without ``certify`` the sound bounds are skipped and the first sequence the exact
        minima clear is returned as ``(shifts (6,), offsets (6,), vertices (12, 3))`` (design
        units): a drag preview and the pattern its release certifies, never a certificate."""
        u = self.unit
        v0, length, d, rho = self.setup(p=p, rho=rho, d=d, d_fraction=d_fraction,
                                        rho_fraction=rho_fraction, max_k=max_k)
        free = np.array([i not in (self.fixed or {}) for i in range(6)])
        patterns = DIGITS[np.all(DIGITS[:, ~free] == 0, axis=1)][1:]  # 3^(6-f) - 1, index order
        tau_unit = np.where(patterns == 2, -1, patterns)
        checks = steps_back = tried = refuted = 0
        where = {"p": p, "d": d * u, "rho": rho * u}

        def over_budget(k: int, checked: int, what: str) -> None:
            if check is not None:
                check()
            if budget is not None and self.work(checked, tried) > budget:
                raise RealizationError(
                    f"work budget of {budget} units used up at k = {k} {what} (p = {p}, "
                    f"d = {d * u:.4g}, rho = {rho * u:.4g}): {checked} thin polylines checked, "
                    f"{steps_back} collision-free ones failed the 2 rho clearance, {refuted} "
                    "refuted by the sound check", "budget")

        for k in range(max_k + 1):
            over_budget(k, checks, "before the level")
            tau = np.zeros((1, 6), int) if k == 0 else k * tau_unit
            polys = v0 + (tau * length / p)[..., None] * self.lp.u
            order = np.argsort(self.lengths(polys), kind="stable")
            tau, polys = tau[order], polys[order]
            for pos in _free_candidates(len(polys), self.colliding(k, tau, polys)):
                over_budget(k, checks + pos + 1, "")
                step = self.step4(polys[pos])
                order = sequence_order(np.sign(tau[pos]))
                examined = 0  # sequences of this candidate, across refutations
                while True:  # the first sequence the sound check (verify) confirms
                    over_budget(k, checks + pos + 1, "while verifying step-4 candidates")
                    seq, n_seq = step.run(order)
                    tried += n_seq
                    examined += n_seq
                    if seq is not None and not certify:
                        return (tau[pos].copy(), OFFSET_WAYS[DIGITS[seq]].copy(),
                                step.points(seq) * self.unit)
                    proof = None if seq is None else self.verify(step, seq)
                    if seq is None or proof is not None:
                        break
                    refuted += 1
                    order = order[np.flatnonzero(order == seq)[0] + 1:]
                if seq is None:
                    steps_back += 1
                    continue
                # counts as in the paper: every polyline of each level entered is checked; one
                # min-distance computation per 12-vertex polyline (42 pairs) examined in order
                stats = {"k": k, "collision_checks": checks + len(polys),
                         "steps_back": steps_back, "min_distance_computations": tried,
                         "offset_rank": min(examined - 1, 2),
                         "collision_checks_sequential": checks + pos + 1,
                         "refuted_by_verification": refuted,
                         "work": self.work(checks + pos + 1, tried)}
                return self.result(step, seq, tau[pos], polys[pos], stats, proof)
            checks += len(polys)
        raise RealizationError(self.cap_message.format(
            max_k=max_k, checks=checks, steps_back=steps_back, **where), "cap-reached")

    def setup(self, *, p: float, rho: float | None, d: float | None, d_fraction: float,
              rho_fraction: float, max_k: int) -> tuple[np.ndarray, float, float, float]:
        """Step 1 and the checked parameters (search units): ``(v0, l, d, rho)``."""
        u = self.unit
        self.v0, self.length = v0, length = self.initial()
        self.d = d = d_fraction * length if d is None else d / u
        self.rho = rho = rho_fraction * d if rho is None else rho / u
        self.p = p
        check_params(p, rho * u, d * u, max_k)
        self.start()
        return v0, length, d, rho

    def run_hint(self, shifts: np.ndarray, offsets: np.ndarray | None, *, p: float,
                 rho: float | None, d: float | None, d_fraction: float, rho_fraction: float,
                 max_k: int, certify: bool = True, refutations: int | None = None) -> Any:
        """Warm start: the shift pattern ``shifts`` ``(6,)`` and ``offsets`` ``(6,)`` of a
        realization of a nearby loop (the previous drag step), tried alone on this loop and
        certified exactly like :meth:`run`'s answers (thin check, exact minima, sound bounds);
        the :meth:`result`, or None when they do not give a collision-free realization here.
        ``offsets`` None: step 4 tries every offset sequence in the paper's order (as
        :meth:`run` does for one thin polyline), giving up after ``refutations`` sequences
        the sound check refutes (None: all). Without ``certify`` the sound bounds are
        skipped and only the vertices ``(12, 3)`` (design units) are returned: a drag
        preview, never a certificate."""
        tau = np.asarray(shifts, int)
        seqs = sequence_order(np.sign(tau)) if offsets is None else np.flatnonzero(
            np.all(OFFSET_WAYS[DIGITS] == np.asarray(offsets, int), axis=1))
        if tau.shape != (6,) or (offsets is not None and len(seqs) != 1):
            raise RealizationError("a warm start needs six shifts and six offsets in "
                                   "{-1, 0, 1}", "bad-parameters")
        v0, length, _, _ = self.setup(p=p, rho=rho, d=d, d_fraction=d_fraction,
                                      rho_fraction=rho_fraction, max_k=max_k)
        k = int(np.abs(tau).max())
        if k > max_k or any(tau[i] for i in self.fixed or {}):
            return None
        polys = v0 + (tau * length / p)[None, :, None] * self.lp.u
        if self.colliding(k, tau[None], polys)(0, 1)[0]:
            return None
        step = self.step4(polys[0])
        while True:  # the first sequence the sound check confirms, as in :meth:`run`
            seq, _ = step.run(seqs)
            if seq is None or not certify:
                return None if seq is None else step.points(seq) * self.unit
            proof = self.verify(step, seq)
            if proof is not None:
                break
            if refutations is not None:
                refutations -= 1
                if refutations <= 0:
                    return None
            seqs = seqs[np.flatnonzero(seqs == seq)[0] + 1:]
        stats = {"k": k, "collision_checks": 1, "steps_back": 0, "min_distance_computations": 1,
                 "offset_rank": 0, "collision_checks_sequential": 1,
                 "refuted_by_verification": 0, "work": self.work(1, 1), "warm_start": 1}
        return self.result(step, seq, tau, polys[0], stats, proof)

    def work(self, checked: int, sequences: int) -> int:
        """Work units so far: thin polylines ``checked``, step-4 ``sequences`` examined (each
        :data:`SEQUENCE_WORK`) and certificate cells (:data:`CELLS_PER_WORK` per unit)."""
        return checked + SEQUENCE_WORK * sequences + self.cells // CELLS_PER_WORK


def realize(
    joint_factors: np.ndarray,
    *,
    p: float = 10.0,
    rho: float | None = None,
    d: float | None = None,
    d_fraction: float = 0.01,
    rho_fraction: float = 0.25,
    fixed: dict[int, float] | None = None,
    max_k: int = 50,
    budget: int | None = None,
    in_unit: float = 1.0,
    check: Callable[[], None] | None = None,
) -> Realization:
    """Collision-free realization of the loop ``joint_factors`` ``(6, 8)`` (Sec. 5.1).

    ``d`` (default ``d_fraction * l``, l = initial polyline length) separates the two vertices
    on each axis, bars have radius ``rho`` (default ``rho_fraction * d``), shifts are
    ``tau l / p``; ``fixed`` maps a vertex index to its held position along its axis (design
    units from the axis foot point). Raises :class:`RealizationError` (``bad-parameters``,
    ``singular-loop``, ``cap-reached`` when ``k`` would exceed ``max_k``, ``budget`` past
    ``budget`` work units, see :meth:`Search.work`). ``joint_factors`` may be given in a unit
    of ``in_unit`` design units (the answer is in design units). ``check()`` is called
    between candidates and may raise to stop the search.
    """
    return Search(joint_factors, fixed, in_unit).run(p=p, rho=rho, d=d, d_fraction=d_fraction,
                                            rho_fraction=rho_fraction, max_k=max_k,
                                            budget=budget, check=check)


def warm_start(joint_factors: np.ndarray, shifts: np.ndarray, offsets: np.ndarray, *,
               p: float = 10.0, rho: float | None = None, d: float | None = None,
               d_fraction: float = 0.01, rho_fraction: float = 0.25,
               fixed: dict[int, float] | None = None, max_k: int = 50) -> Realization | None:
    """The realization of ``joint_factors`` with the ``shifts`` and ``offsets`` of a nearby
    loop's realization (e.g. the previous step of a drag), certified as :func:`realize`'s;
    None when they do not realize this loop (then run :func:`realize`)."""
    return Search(joint_factors, fixed).run_hint(shifts, offsets, p=p, rho=rho, d=d,
                                                 d_fraction=d_fraction,
                                                 rho_fraction=rho_fraction, max_k=max_k)
