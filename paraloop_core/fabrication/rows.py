"""The certified rows and the linear programme of the parts' radii over them.

The realization proves, over the whole cycle, a lower bound ``L`` (design units) of the
distance between the centre lines of every pair of segments of different links that must stay
apart (``Realization.pair_lower``: bars ``S_iE_i`` and pins ``E_iS_{i+1}``) and of each pair of
consecutive bars (``joint_lower``); two consecutive pins are fixed in the link between them, so
their distance is the one at home (:class:`Bounds`). A link lies in a capsule of radius ``R_i``
(its hexagonal bar's corner radius) about its bar, and a joint's bosses and hardware in a
capsule of radius ``max(B_j, h_j)`` (boss ``B_j``, hardware ``h_j``) about its pin extended by
``x_j`` past the pin's ends (a point within ``x`` of a segment's end is within ``x`` of the
segment). So at ``k`` mm per unit the parts keep the gap ``g`` if ``r_a + r_b + g <= k L - x_a -
x_b`` for every row: one small linear programme in the twelve radii (:func:`radii`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linprog

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import joints
from paraloop_core.fabrication.profiles import MIN_WALL_MM
from paraloop_core.linkage import loops

#: Boss radius per bar corner radius: room for a fillet of a quarter of the bar.
BOSS_PER_BAR = 1.25


@dataclass(frozen=True)
class Bounds:
    """A realization's certified bounds (design units): ``points`` ``(12, 3)``, ``rows``
    ``(N, 4)`` (edge, edge, link, link) with ``lower`` ``(N,)``, consecutive bars
    ``joint_lower`` ``(6,)``, consecutive pins at home ``pin_pin`` ``(6,)`` (joint j with j+1),
    ``extent`` (longest side of the polyline's box), the joint ``axes`` ``(6, 6)``; with an
    end-effector its certified rows ``ee_rows`` ``(M, 3)`` (link 3's part: 3 a bar ``S_3 L``
    or ``R E_3``, -1 P itself; an edge; that edge's link) with ``ee_lower`` ``(M,)``, and how
    far (mm) P's solid reaches past its surface ``ee_reach`` (a sheet's half thickness)."""

    points: np.ndarray
    rows: np.ndarray
    lower: np.ndarray
    joint_lower: np.ndarray
    pin_pin: np.ndarray
    extent: float
    axes: np.ndarray
    ee_rows: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), int))
    ee_lower: np.ndarray = field(default_factory=lambda: np.zeros(0))
    ee_reach: float = 0.0

    @property
    def bar_lengths(self) -> np.ndarray:
        return np.linalg.norm(self.points[1::2] - self.points[0::2], axis=-1)


def bounds_of(real, ee=None) -> Bounds:
    """:class:`Bounds` of a ``certified.Realization`` (with the rows of its end-effector
    realization ``ee``: :func:`ee_rows`)."""
    from paraloop_core.realization.clearance import segment_distance

    pts = np.asarray(real.points, float)
    low = np.asarray(real.pair_lower, float)
    # consecutive bars i, i+1 (inf where a bar is not there: link 3 with an end-effector)
    jl = np.full(6, np.inf)
    jl[np.asarray(real.joint_pairs)[:, 2]] = np.asarray(real.joint_lower, float)
    if not (np.all(np.isfinite(low)) and not np.any(np.isnan(jl))):
        raise FabricationError("the realization has no proven pair bounds", "bad-parameters")
    e, s = pts[1::2], np.roll(pts[0::2], -1, axis=0)  # pin j: E_j -> S_{j+1}
    pp = segment_distance(e, s, np.roll(e, -1, axis=0), np.roll(s, -1, axis=0))
    return Bounds(pts, np.asarray(real.pairs), low, jl, np.asarray(pp, float),
                  float(np.max(np.ptp(pts, axis=0))), loops.factor_axes(real.joint_factors),
                  *(() if ee is None else ee_rows(ee)))


def ee_rows(ee) -> tuple[np.ndarray, np.ndarray, float]:
    """The rows an end-effector realization certifies (``ee_certificate``: the bars ``S_3 L``,
    ``R E_3`` and P against every edge of the other links, exact minima over the cycle), and
    those two bars against the neighbouring bars across their joints (proven here), as
    ``(rows (M, 3), lower (M,), reach)`` of :class:`Bounds`; those within link 3 (static) left
    out. Without them the sizing grew a neighbour's bar into P (the verification refused)."""
    from paraloop_core.realization import verify
    from paraloop_core.realization.ee_certificate import BASE_PAIRS, MESH, STEP4_ROWS

    out, low = [], []
    for (part, edge, (la, lb), _), d in zip(STEP4_ROWS[len(BASE_PAIRS):], ee.ee_distance,
                                            strict=True):
        if la != lb:
            out.append((-1 if part[0] == MESH else 3, edge[0], lb))
            low.append(float(d))
    # the bars S_3 L and R E_3 against their neighbours' bars across joints 2 and 3, which the
    # certificate leaves to the joint (the paper's links meet there): proven here as the
    # consecutive bars of a plain realization are (certified.joint_bounds)
    real = ee.realization
    pts, (s3, left, right, e3) = np.asarray(real.points, float), ee.end_link()
    fixed = np.stack([pts[[4, 5]], pts[[8, 9]]])  # S_2 E_2, S_4 E_4
    moving = np.stack([[s3, left], [right, e3]])
    bounds = verify.pair_bounds(real.joint_factors, fixed, moving, np.array([[2, 3], [4, 3]]),
                                1e-3 * real.length)
    out += [(3, 4, 2), (3, 8, 4)]
    low += list(bounds.lower - real.reading_gap)
    # an open P prints thickened by endlink.SHEET_MM (= MIN_WALL_MM), half on each side
    reach = 0.0 if ee.effector.closed else MIN_WALL_MM / 2
    return np.array(out, int).reshape(-1, 3), np.array(low), reach


def radii(b: Bounds, k: float, rmin: np.ndarray, rcap: float | np.ndarray, bmin: float,
          env: np.ndarray, gaps: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Bar corner radii and boss radii ``(6,), (6,)`` (mm) at ``k`` mm per unit (module
    docstring), or None when no radii meet every row; ``rmin`` ``(6,)``, ``rcap``, ``bmin``
    the bounds, ``env`` ``(6, 2)`` each joint's :func:`joints.envelope` (how far its bosses
    reach past the pin's ends; the largest radius plus reach of its metal pieces), ``gaps``
    ``(6, 6)`` the gap each pair of links keeps (mm)."""
    rows_a, rows_b = [], []

    def shapes(e: int) -> list[tuple[int | None, float]]:
        """Capsules of edge e as (radius variable or None, reach subtracted from the bound):
        a bar's R; a pin's bosses (B, reach) and its metal pieces (constant, nothing)."""
        if e % 2 == 0:
            return [(e // 2, 0.0)]
        j = e // 2
        return [(6 + j, float(env[j, 0]))] + ([(None, float(env[j, 1]))] if env[j, 1] > 0
                                              else [])

    def add(e1: list, e2: list, budget: float) -> None:
        for (v1, x1), (v2, x2) in itertools.product(e1, e2):
            a = np.zeros(12)
            for v in (v1, v2):
                if v is not None:
                    a[v] += 1.0
            rows_a.append(a)
            rows_b.append(budget - x1 - x2)

    for (e1, e2, la, lb), low in zip(b.rows, b.lower, strict=True):
        add(shapes(int(e1)), shapes(int(e2)), k * low - gaps[la, lb])
    for (part, e, lb), low in zip(b.ee_rows, b.ee_lower, strict=True):  # link 3's P and bars
        add([(3, 0.0)] if part == 3 else [(None, b.ee_reach)], shapes(int(e)),
            k * low - gaps[3, lb])
    for i in range(6):  # consecutive bars i, i+1 and consecutive pins i, i+1
        j = (i + 1) % 6
        if np.isfinite(b.joint_lower[i]):
            add(shapes(2 * i), shapes(2 * j), k * b.joint_lower[i] - gaps[i, j])
        add(shapes(2 * i + 1), shapes(2 * j + 1), k * b.pin_pin[i] - gaps[i, (i + 2) % 6])
    for j in range(6):  # bosses hold a fillet around both bars they join
        for link in (j, (j + 1) % 6):
            a = np.zeros(12)
            a[link], a[6 + j] = BOSS_PER_BAR, -1.0
            rows_a.append(a)
            rows_b.append(0.0)
    a_ub, b_ub = np.array(rows_a), np.array(rows_b)
    if np.any((np.abs(a_ub).sum(axis=1) == 0) & (b_ub < 0)):
        return None  # metal pieces alone are too close for a row
    top = np.broadcast_to(np.asarray(rcap, float), (6,))
    bounds = [(float(rmin[i]), float(top[i])) for i in range(6)] + [(bmin, None)] * 6
    # 1) the largest thinnest bar t (variable 12): t - R_i <= 0
    a1 = np.hstack([a_ub, np.zeros((len(a_ub), 1))])
    floor = np.zeros((6, 13))
    floor[np.arange(6), np.arange(6)], floor[:, 12] = -1.0, 1.0
    res = linprog(np.r_[np.zeros(12), -1.0], A_ub=np.vstack([a1, floor]),
                  b_ub=np.r_[b_ub, np.zeros(6)], bounds=[*bounds, (None, None)],
                  method="highs")
    if not res.success:
        return None
    t = res.x[12]
    # 2) the largest bars with every bar >= t, then the smallest bosses that hold them
    bounds2 = [(max(lo, t * (1 - 1e-6)), hi) for lo, hi in bounds[:6]] + bounds[6:]
    res = linprog(np.r_[-np.ones(6), 0.05 * np.ones(6)], A_ub=a_ub, b_ub=b_ub, bounds=bounds2,
                  method="highs")
    x = res.x if res.success else np.r_[np.full(6, t), res.x[6:] if res.x is not None else
                                        np.full(6, bmin)]
    # the solver's round-off must not overstep a row: shrink towards the floors
    over = a_ub @ x - b_ub
    if np.any(over > 1e-9):
        return None if np.any(over > 1e-6) else (x[:6] * (1 - 1e-7), x[6:] * (1 - 1e-7))
    return x[:6], x[6:]


def least_bosses(r: np.ndarray, bmin: float) -> np.ndarray:
    """The least boss radius ``(6,)`` (mm) of each joint j for bars ``r`` ``(6,)``: the
    fillet round both bars it joins (links j and j+1, :data:`BOSS_PER_BAR`), at least
    ``bmin``."""
    return np.maximum(bmin, BOSS_PER_BAR * np.maximum(r, np.roll(r, -1)))


def envelopes(layouts: tuple[joints.Joint, ...]) -> np.ndarray:
    """:func:`joints.envelope` of each joint ``(6, 2)`` (mm)."""
    return np.array([joints.envelope(j) for j in layouts])
