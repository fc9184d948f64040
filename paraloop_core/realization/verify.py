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
  are halved (far pairs need no more absolute precision than near ones; a flat minimum, e.g.
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
#: Cells per chart at the start, the most cells one pair may visit, and halving rounds.
_START_CELLS = 64
_MAX_CELLS = 200_000
_MAX_ROUNDS = 48


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
    out = np.array([np.inf, np.inf, -np.inf, 0.0])[:, None].repeat(n, axis=1)
    cache: dict[tuple[int, int], tuple[_Chain, _Chain]] = {}
    for row in range(n):  # a few dozen pairs; each one is vectorized over its cells
        key = (int(links[row, 0]), int(links[row, 1]))
        if key not in cache:
            chain = loops.relative_chain(jf, *key)
            lin = poly.reparametrize(chain, a, b)
            lin = lin / np.abs(lin[..., :4]).max(axis=(-2, -1), keepdims=True)
            axes = loops.factor_axes(chain[:, 0])
            # chart s and chart w = 1/s (w L(1/w): reversed coefficients)
            cache[key] = (_Chain(lin, axes), _Chain(lin[:, ::-1], axes))
        h = hints[row][~np.isnan(hints[row])]
        s_hint = np.where(np.isinf(h), np.inf, (h - b) / a)
        upper, s_best, lower, cells = _one_pair(cache[key], fixed[row], moving[row], tol,
                                                s_hint, need)
        out[:, row] = upper, (np.inf if np.isinf(s_best) else a * s_best + b), lower, cells
        if upper < need:
            break
    return PairBounds(out[0], out[1], out[2], out[3].astype(int))


def _one_pair(charts: tuple[_Chain, _Chain], fixed: np.ndarray, moving: np.ndarray,
              tol: float, s_hint: np.ndarray, need: float) -> tuple[float, float, float, int]:
    """Branch and bound of one pair over both charts: ``(upper, s, lower, cells)``."""
    # the exact candidates (hints) only seed the best distance: cells prove the bound
    inner = np.abs(s_hint) <= 1
    w_hint = np.where(np.isinf(s_hint), 0.0, 1.0 / np.where(inner, 1.0, s_hint))
    seeds = [(0, s_hint[inner]), (1, w_hint[~inner])]
    best, best_s = np.inf, np.inf
    for chart, x in seeds:
        if x.size:
            d, _ = _cells(charts[chart], fixed, moving, x, np.zeros_like(x))
            k = int(np.argmin(d))
            if d[k] < best:
                best, best_s = float(d[k]), _to_s(chart, float(x[k]))
    r0 = 1.0 / _START_CELLS
    centres = -1.0 + r0 * (2 * np.arange(_START_CELLS) + 1)
    front = [(0, centres, np.full(_START_CELLS, r0)), (1, centres, np.full(_START_CELLS, r0))]
    lower, visited = np.inf, 0
    for _ in range(_MAX_ROUNDS):
        evaluated = []
        for chart, x, r in front:
            if x.size:
                d, m = _cells(charts[chart], fixed, moving, x, r)
                low = np.full_like(d, -np.inf)
                np.subtract(d, m, out=low, where=np.isfinite(m) & np.isfinite(d))
                evaluated.append((chart, x, r, d, low))
                k = int(np.argmin(d))
                if d[k] < best:
                    best, best_s = float(d[k]), _to_s(chart, float(x[k]))
                visited += x.size
        front = []
        for chart, x, r, _d, low in evaluated:
            # precise near the minimum; a pair proven clear of twice what is needed is
            # done (its minimum is then known to lower precision: lower <= true <= upper)
            open_ = (low < best - tol - RELATIVE * best) & ~((need > 0) & (low >= 2.0 * need))
            if visited >= _MAX_CELLS:
                open_[:] = False
            lower = min(lower, float(low[~open_].min(initial=np.inf)))
            x, r = x[open_], r[open_] / 2
            front.append((chart, np.concatenate([x - r, x + r]), np.concatenate([r, r])))
        if all(x.size == 0 for _, x, _ in front):
            break
        if best < need:  # refuted: an attained distance below what is needed
            return best, best_s, -np.inf, visited
    if any(x.size for _, x, _ in front):  # rounds exhausted: unbounded cells left (unsure)
        lower = -np.inf
    return best, best_s, min(lower, best), visited


def _to_s(chart: int, x: float) -> float:
    return x if chart == 0 else (np.inf if x == 0 else 1.0 / x)


@dataclass(frozen=True)
class _Chain:
    """One chart of a relative motion: linear factors ``(k, 2, 8)`` (ascending in the chart
    variable, the motion is their product) and their unit Plücker axes ``(k, 6)``."""

    lin: np.ndarray
    axes: np.ndarray


def _cells(chain: _Chain, fixed: np.ndarray, moving: np.ndarray, x: np.ndarray,
           r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distances at the cell centres ``x`` ``(C,)`` (upper, rounding included) and displacement
    bounds ``(C,)`` over the cells of radii ``r`` (module docstring; ``inf`` where a factor
    degenerates, which a generic motion never does)."""
    u = np.stack([x, x - r, x + r])  # (3, C)
    q = chain.lin[:, None, None, 0] + chain.lin[:, None, None, 1] * u[None, :, :, None]
    pn = np.linalg.norm(q[..., :4], axis=-1, keepdims=True)  # (k, 3, C, 1)
    ok = np.all(pn[..., 0] > 1e-150, axis=(0, 1))
    q = q / np.where(pn > 1e-150, pn, 1.0)
    disp, y = chain_sweep(q[:, 0], [q[:, 1], q[:, 2]], chain.axes, moving[None])
    moment = chain.axes[:, 3:]
    # rounding of the composed points and of the chords: far below 1e-12 of the frame's size
    size = np.abs(fixed).max() + np.abs(moving).max() + 2.0 * np.abs(moment).sum()
    slack = 1e-12 * size * (1.0 + disp.max(axis=1) / max(size, 1e-300))
    d = segment_distance(fixed[0], fixed[1], y[:, 0], y[:, 1])
    return (np.where(ok, d + slack, np.inf),
            np.where(ok, disp.max(axis=1) + 2.0 * slack, np.inf))


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
