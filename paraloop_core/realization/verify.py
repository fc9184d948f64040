"""Sound per-pair minimum distances over the whole cycle: the certificate's last word.

The critical-point polynomials of :mod:`clearance` find the minima fast, but their roots are
only as good as float64 root finding of degree <= 17 polynomials: near a fast turn (a norm root
close to the real axis) or near ``t = inf`` a minimum can be missed. So every certified pair is
re-checked here by branch and bound with rigorous displacement bounds:

* The parameter is conditioned, ``t = a s + b`` (:func:`clearance.charts`: the norm
  roots gather round ``s = i``), and the projective line is covered by two charts,
  ``s in [-1, 1]`` and ``w = 1/s in [-1, 1]`` (the reversed polynomial; ``w = 0`` is
  ``t = inf``), each split into cells ``[c - r, c + r]``.
* The moving link's motion is the product of its joint factors, ``L_0(t) ... L_{k-1}(t)``
  (:func:`loops.relative_chain`), each a rotation about a fixed joint axis whose half angle is
  the argument of a point moving on a line in the quaternion plane ``span(1, axis)``. Over a
  cell the half angle of factor m sweeps ``delta_m``: the angle between its (primal) values at
  the centre and an end (monotone from the centre: a line seen from the origin). Telescoping
  the product, a moving point ``y`` is displaced by at most
  ``sum_m 2 sin(min(delta_m, pi/2)) * dist(y_m(c), axis_m)`` with ``y_m`` the point carried
  by the inner factors at the centre. The factored form stays exact where the expanded
  polynomial loses every digit: near a fast turn (a norm root close to the real axis) ``|P|^2``
  cancels, while each factor is just a rotation. A rigid motion is affine in the point, so the
  moving segment's Hausdorff displacement is at most its endpoints' larger one, and the
  segment distance changes by at most that much on the cell: ``d(c) - m`` is a lower bound.
* Cells whose lower bound is not within ``tol + RELATIVE * best`` of the best distance found
  are split in four (far pairs need no more absolute precision than near ones; a flat minimum, e.g.
  two points on a common rotation axis, would otherwise need endless cells).

Result per pair: ``upper`` (a distance attained at ``t``: never below the true minimum) and
``lower`` (proven: never above it), ``upper - lower <= tol + RELATIVE * upper`` unless the cell
cap was reached or (with ``need``) ``lower >= 2 need`` already;
then ``lower`` is still sound and the caller must treat a pair it cannot clear as unsure.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from paraloop_core.algebra import poly
from paraloop_core.linkage import loops
from paraloop_core.realization.clearance import charts, segment_distance
from paraloop_core.realization.motion_bound import chain_sweep

#: Wanted gap ``upper - lower`` relative to the pair's distance (on top of the absolute tol).
RELATIVE = 1e-4
#: Cells per chart at the start, the most cells one pair may visit, and splitting rounds.
_START_CELLS = 8
_MAX_CELLS = 200_000
_MAX_ROUNDS = 48
#: Parts an open cell is split into per round (fewer rounds: each costs array calls).
_SPLIT = 4
#: Pairs bounded together (one batch of cells): all 42 of a polyline (array calls, not
#: cells, dominate; a refutation is rare and still stops the search at its round).
_BATCH = 42


@dataclass(frozen=True)
class PairBounds:
    """Per pair ``(N,)``: ``upper`` attained distance at parameter ``t`` (inf = home),
    ``lower`` proven lower bound of the minimum over ``R u {inf}``, ``cells`` visited."""

    upper: np.ndarray
    t: np.ndarray
    lower: np.ndarray
    cells: np.ndarray


def pair_bounds(joint_factors: np.ndarray, fixed: np.ndarray, moving: np.ndarray,
                links: np.ndarray, tol: float, hints: np.ndarray | None = None,
                need: float = -np.inf) -> PairBounds:
    """Sound minimum distances of ``N`` segment pairs over the cycle (module docstring).

    ``fixed`` / ``moving`` ``(N, 2, 3)``: segments of links ``links[:, 0]`` / ``links[:, 1]``
    at home (base frame, design units); the second moves by the relative motion
    ``R_{link0, link1}(t)``. ``tol`` > 0 (design units) is the wanted ``upper - lower``;
    ``hints`` ``(N,)`` or ``(N, H)`` candidate parameters t (e.g. exact critical points).
    Returned ``t`` are in the caller's parameter. With ``need``, the work stops at the first
    pair with a distance below it (that pair's ``upper`` is that distance; the pairs not
    reached get ``upper = inf``, ``lower = -inf``): enough to refute a candidate.
    """
    jf = np.asarray(joint_factors, dtype=np.float64)
    fixed = np.asarray(fixed, dtype=np.float64).reshape(-1, 2, 3)
    moving = np.asarray(moving, dtype=np.float64).reshape(-1, 2, 3)
    links = np.asarray(links, dtype=int).reshape(-1, 2)
    if not (len(fixed) == len(moving) == len(links)) or not (np.isfinite(tol) and tol > 0):
        raise ValueError("pair_bounds needs equally many fixed, moving segments and link "
                         f"pairs and tol > 0, got {len(fixed)}, {len(moving)}, {len(links)}, "
                         f"{tol!r}")
    n = len(fixed)
    hints = np.empty((n, 0)) if hints is None else np.asarray(hints, float).reshape(n, -1)
    (a, b), _ = charts(jf)
    keys, chain_of = np.unique(links, axis=0, return_inverse=True)
    chains = _Chains.of(jf, keys, a, b)
    chain_of = chain_of.ravel()
    upper, s_best = np.full(n, np.inf), np.full(n, np.inf)
    lower, cells = np.full(n, -np.inf), np.zeros(n, int)
    for lo in range(0, n, _BATCH):  # batches in the given order: a refutation stops early
        part = slice(lo, min(lo + _BATCH, n))
        upper[part], s_best[part], lower[part], cells[part] = _branch_and_bound(
            chains, chain_of[part], fixed[part], moving[part], tol, (hints[part] - b) / a,
            need)
        if (upper[part] < need).any():
            break
    # the work stops at the first pair (in the given order) refuted: later ones not reached
    refuted = np.flatnonzero(upper < need)
    if refuted.size:
        late = np.arange(n) > refuted[0]
        upper[late], s_best[late], lower[late], cells[late] = np.inf, np.inf, -np.inf, 0
    t = np.where(np.isinf(s_best), np.inf, a * s_best + b)
    return PairBounds(upper, t, lower, cells)


@dataclass(frozen=True)
class _Chains:
    """The relative motions of the link pairs, both charts: ``lin_s`` / ``lin_w`` ``(K, 3, 2,
    8)`` linear factors (ascending in the chart variable ``s`` / ``w = 1/s``: reversed
    coefficients; the motion is their product, outermost first) and unit Plücker axes
    ``axes`` ``(K, 3, 6)``. Chains of fewer than three factors are padded with the constant
    factor 1 innermost: it never moves a point, so every pair runs in one batch."""

    lin_s: np.ndarray
    lin_w: np.ndarray
    axes: np.ndarray

    @staticmethod
    def of(jf: np.ndarray, keys: np.ndarray, a: float, b: float) -> _Chains:
        shape = (len(keys), 3)
        lin_s, lin_w = np.zeros(shape + (2, 8)), np.zeros(shape + (2, 8))
        lin_s[..., 0, 0] = lin_w[..., 0, 0] = 1.0
        axes = np.zeros(shape + (6,))
        axes[..., 2] = 1.0
        for c, (i, j) in enumerate(keys):  # at most 15 link pairs: set-up only
            chain = loops.relative_chain(jf, int(i), int(j))
            lin = poly.reparametrize(chain, a, b)
            lin = lin / np.abs(lin[..., :4]).max()
            k = len(chain)
            lin_s[c, :k], lin_w[c, :k] = lin, lin[:, ::-1]
            axes[c, :k] = loops.factor_axes(chain[:, 0])
        return _Chains(lin_s, lin_w, axes)


def _branch_and_bound(chains: _Chains, chain_of: np.ndarray, fixed: np.ndarray,
                      moving: np.ndarray, tol: float, s_hints: np.ndarray, need: float
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Branch and bound of all pairs at once over both charts: per pair ``(upper, s, lower,
    cells)``. Each pair's cells open and close on its own best distance, exactly as if the
    pairs ran one by one; cells are kept in pair order, chart s before chart w."""
    n = len(fixed)
    best, best_s = np.full(n, np.inf), np.full(n, np.inf)
    lower, visited = np.full(n, np.inf), np.zeros(n, int)
    done = np.zeros(n, bool)

    def evaluate(chart: np.ndarray, x: np.ndarray, r: np.ndarray, row: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
        c = chain_of[row]
        lin = np.where((chart == 0)[:, None, None, None], chains.lin_s[c], chains.lin_w[c])
        d, m = _cells(lin, chains.axes[c], fixed[row], moving[row], x, r)
        # the first smallest distance of each pair improves its best (ties: earlier cell)
        order = np.lexsort((np.arange(len(d)), d, row))
        first = order[np.r_[True, row[order][1:] != row[order][:-1]]]
        better = first[d[first] < best[row[first]]]
        best[row[better]] = d[better]
        best_s[row[better]] = np.where(chart[better] == 0, x[better], np.where(
            x[better] == 0, np.inf, 1.0 / np.where(x[better] == 0, 1.0, x[better])))
        return d, m

    # the exact candidates (hints) only seed the best distance: cells prove the bound
    rows, cols = np.nonzero(~np.isnan(s_hints))
    h = s_hints[rows, cols]
    inner = np.abs(h) <= 1
    w = np.where(np.isinf(h), 0.0, 1.0 / np.where(inner | np.isinf(h), 1.0, h))
    seed = np.lexsort((~inner, rows))  # per pair: chart s seeds, then chart w
    if seed.size:
        evaluate(np.where(inner, 0, 1)[seed], np.where(inner, h, w)[seed],
                 np.zeros(seed.size), rows[seed])
    r0 = 1.0 / _START_CELLS
    centres = -1.0 + r0 * (2 * np.arange(_START_CELLS) + 1)
    row = np.repeat(np.arange(n), 2 * _START_CELLS)
    chart = np.tile(np.repeat([0, 1], _START_CELLS), n)
    x = np.tile(centres, 2 * n)
    r = np.full(x.size, r0)
    for _ in range(_MAX_ROUNDS):
        d, m = evaluate(chart, x, r, row)
        low = np.full_like(d, -np.inf)
        np.subtract(d, m, out=low, where=np.isfinite(m) & np.isfinite(d))
        visited += np.bincount(row, minlength=n)
        # precise near the minimum; a pair proven clear of twice what is needed is done (its
        # minimum is then known to lower precision: lower <= true <= upper)
        b = best[row]
        open_ = (low < b - tol - RELATIVE * b) & ~((need > 0) & (low >= 2.0 * need))
        open_ &= visited[row] < _MAX_CELLS
        np.minimum.at(lower, row[~open_], low[~open_])
        keep = np.flatnonzero(open_)
        has_front = np.bincount(row[keep], minlength=n) > 0
        done |= ~has_front  # finished: lower = min(lower, best) below
        refuted = has_front & (best < need)  # an attained distance below what is needed
        lower[refuted], done[refuted] = -np.inf, True
        keep = keep[~refuted[row[keep]]]
        if keep.size == 0:
            break
        # split in _SPLIT: per pair and chart, the leftmost parts first (pair order kept)
        ch, xk, rk, rw = chart[keep], x[keep], r[keep] / _SPLIT, row[keep]
        part = np.repeat(np.arange(_SPLIT), keep.size)
        order = np.lexsort((np.arange(_SPLIT * keep.size), part, np.tile(rw * 2 + ch, _SPLIT)))
        chart = np.tile(ch, _SPLIT)[order]
        x = (np.tile(xk, _SPLIT) + (2 * part + 1 - _SPLIT) * np.tile(rk, _SPLIT))[order]
        r = np.tile(rk, _SPLIT)[order]
        row = np.tile(rw, _SPLIT)[order]
    else:  # rounds exhausted: pairs with unbounded cells left are unsure
        lower[np.unique(row)] = -np.inf
    finished = lower > -np.inf
    lower[finished] = np.minimum(lower[finished], best[finished])
    return best, best_s, lower, visited


def _cells(lin: np.ndarray, axes: np.ndarray, fixed: np.ndarray, moving: np.ndarray,
           x: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distances at the cell centres ``x`` ``(C,)`` (upper, rounding included) and displacement
    bounds ``(C,)`` over the cells of radii ``r``, each cell with its chain's linear factors
    ``lin`` ``(C, k, 2, 8)``, axes ``(C, k, 6)`` and segments ``fixed``, ``moving`` ``(C, 2,
    3)`` (module docstring; ``inf`` where a factor degenerates, which a generic motion never
    does). The factors are built per component (``(8, k, C)``, long inner loops) and handed
    to :func:`chain_sweep` as views."""
    l0 = np.ascontiguousarray(lin[:, :, 0, :].T)  # (8, k, C)
    l1 = np.ascontiguousarray(lin[:, :, 1, :].T)
    unit, ok = [], np.ones(len(x), bool)
    for u in (x, x - r, x + r):  # the factors at the centre and both ends, unit primal parts
        q = l0 + l1 * u
        pn = np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])  # (k, C)
        ok &= np.all(pn > 1e-150, axis=0)
        q /= np.where(pn > 1e-150, pn, 1.0)
        unit.append(np.moveaxis(q, 0, -1))  # (k, C, 8) view
    disp, y = chain_sweep(unit[0], unit[1:], axes.transpose(1, 0, 2), moving)
    disp = disp.max(axis=1)
    moment = axes[..., 3:]
    # rounding of the composed points and of the chords: far below 1e-12 of the frame's size
    size = (np.abs(fixed).max(axis=(1, 2)) + np.abs(moving).max(axis=(1, 2))
            + 2.0 * np.abs(moment).sum(axis=(1, 2)))
    slack = 1e-12 * size * (1.0 + disp / np.maximum(size, 1e-300))
    d = segment_distance(fixed[:, 0], fixed[:, 1], y[:, 0], y[:, 1])
    return np.where(ok, d + slack, np.inf), np.where(ok, disp + 2.0 * slack, np.inf)


#: The six pairs of consecutive bars ``(S_iE_i, S_{i+1}E_{i+1})`` ``(6, 4)`` (edge, edge, link,
#: link): they turn about their common axis and, contrary to the paper's remark, the offset
#: alone does not keep them 2 rho apart when both lean the same way.
JOINT_PAIRS = np.array([(2 * i, 2 * ((i + 1) % 6), i, (i + 1) % 6) for i in range(6)])


def polyline_bounds(joint_factors: np.ndarray, points: np.ndarray, pairs: np.ndarray,
                    tol: float, hints: np.ndarray | None = None,
                    need: float = -np.inf) -> PairBounds:
    """:func:`pair_bounds` of edge pairs ``pairs`` ``(N, 4)`` (edge 1, edge 2, link 1, link 2;
    edge e joins ``points[e]`` and ``points[e + 1 mod 12]``) of a 12-vertex polyline at home."""
    pts = np.asarray(points, dtype=np.float64)
    e1, e2 = pairs[:, 0], pairs[:, 1]
    fixed = np.stack([pts[e1], pts[(e1 + 1) % len(pts)]], axis=1)
    moving = np.stack([pts[e2], pts[(e2 + 1) % len(pts)]], axis=1)
    return pair_bounds(joint_factors, fixed, moving, pairs[:, 2:], tol, hints, need)
