"""Sound per-pair minimum distances over the whole cycle: the certificate's last word.

The critical-point polynomials of :mod:`clearance` find the minima fast, but their roots are
only as good as float64 root finding of degree <= 22 polynomials: near a fast turn (a norm root
close to the real axis) or near ``t = inf`` a minimum can be missed. So every certified pair is
re-checked here by branch and bound with rigorous displacement bounds:

* The parameter is conditioned, ``t = a s + b`` (:func:`factor.conditioning_batch`: the norm
  roots gather round ``s = i``), and the projective line is covered by two charts,
  ``s in [-1, 1]`` and ``w = 1/s in [-1, 1]`` (the reversed polynomial; ``w = 0`` is
  ``t = inf``), each split into cells ``[c - r, c + r]``.
* A moving point is ``x(s) = X(s) / N(s)`` with polynomials ``X`` (vector) and ``N = |P|^2``.
  With their exact Taylor coefficients at the cell centre, for ``|delta| <= r``:
  ``|x(c + delta) - x(c)| <= sum_n |X_n N_0 - X_0 N_n| r^n / (N_0 (N_0 - sum_n |N_n| r^n))``
  (``n >= 1``; valid while the bracket is positive). A rigid motion is affine in the point, so
  the moving segment's Hausdorff displacement is at most its endpoints' larger one, and the
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
from math import comb

import numpy as np

from paraloop_core.algebra import dq, factor, poly
from paraloop_core.linkage import loops
from paraloop_core.realization.clearance import segment_distance

_EPS = np.finfo(float).eps
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
    a, b, _ = factor.conditioning_batch(loops.relative_motion(jf, 0, 3))
    a, b = float(a), float(b)
    out = np.array([np.inf, np.inf, -np.inf, 0.0])[:, None].repeat(n, axis=1)
    cache: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
    for row in range(n):  # a few dozen pairs; each one is vectorized over its cells
        key = (int(links[row, 0]), int(links[row, 1]))
        if key not in cache:
            c = poly.reparametrize(loops.relative_motion(jf, *key), a, b)
            c = c / np.abs(c[..., :4]).max()
            cache[key] = (c, c[::-1])  # chart s and chart w = 1/s (reversed coefficients)
        h = hints[row][~np.isnan(hints[row])]
        s_hint = np.where(np.isinf(h), np.inf, (h - b) / a)
        upper, s_best, lower, cells = _one_pair(cache[key], fixed[row], moving[row], tol,
                                                s_hint, need)
        out[:, row] = upper, (np.inf if np.isinf(s_best) else a * s_best + b), lower, cells
        if upper < need:
            break
    return PairBounds(out[0], out[1], out[2], out[3].astype(int))


def _one_pair(charts: tuple[np.ndarray, np.ndarray], fixed: np.ndarray, moving: np.ndarray,
              tol: float, s_hint: np.ndarray, need: float) -> tuple[float, float, float, int]:
    """Branch and bound of one pair over both charts: ``(upper, s, lower, cells)``."""
    maps = [_point_maps(c, moving) for c in charts]
    # the exact candidates (hints) only seed the best distance: cells prove the bound
    inner = np.abs(s_hint) <= 1
    w_hint = np.where(np.isinf(s_hint), 0.0, 1.0 / np.where(inner, 1.0, s_hint))
    seeds = [(0, s_hint[inner]), (1, w_hint[~inner])]
    best, best_s = np.inf, np.inf
    for chart, x in seeds:
        if x.size:
            d, _ = _cells(maps[chart], fixed, x, np.zeros_like(x))
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
                d, m = _cells(maps[chart], fixed, x, r)
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


def _point_maps(c: np.ndarray, moving: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Numerators ``X`` ``(2, 3, D+1)`` of the two moved endpoints and ``N`` ``(D+1,)``
    (ascending, ``D = 2k``): ``R(s)(x) = X(s) / N(s)`` (point action of :mod:`dq`)."""
    p, d = c[:, :4], c[:, 4:]
    k = len(c) - 1
    xq = np.concatenate([np.zeros((2, 1)), moving], axis=1)  # (2, 4)
    pc = dq.qconj(p)
    # term (i, j) of P x P~ + 2 D P~ contributes to power i + j
    pxp = dq.qmul(dq.qmul(p[None, :, None], xq[:, None, None]), pc[None, None, :])  # (2,K,K,4)
    dpc = 2.0 * dq.qmul(d[:, None], pc[None, :])  # (K, K, 4)
    nn = np.sum(p[:, None] * p[None, :], axis=-1)  # (K, K)
    x_num = np.zeros((2, 3, 2 * k + 1))
    norm = np.zeros(2 * k + 1)
    for i in range(k + 1):
        for j in range(k + 1):
            x_num[:, :, i + j] += (pxp[:, i, j] + dpc[i, j])[:, 1:]
            norm[i + j] += nn[i, j]
    return x_num, norm


def _taylor(coef: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Taylor coefficients ``(C, ..., D+1)`` at centres ``x`` ``(C,)`` of polynomials
    ``coef`` ``(..., D+1)`` (ascending): ``p(x + h) = sum_n T_n h^n``."""
    deg = coef.shape[-1] - 1
    shift = np.zeros((len(x), deg + 1, deg + 1))
    for m in range(deg + 1):
        for n in range(m + 1):
            shift[:, n, m] = comb(m, n) * x ** (m - n)
    return np.einsum("cnm,...m->c...n", shift, coef)


def _cells(maps: tuple[np.ndarray, np.ndarray], fixed: np.ndarray, x: np.ndarray,
           r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distances at the cell centres ``x`` ``(C,)`` and displacement bounds ``(C,)`` over the
    cells of radii ``r`` (``inf`` where the norm may vanish on the cell)."""
    x_num, norm = maps
    tx = _taylor(x_num, x)  # (C, 2, 3, D+1)
    tn = _taylor(norm, x)  # (C, D+1)
    n0 = tn[:, 0]
    # float64 evaluation error of the centre values (Horner-type sums of |terms|)
    mono = np.abs(x[:, None]) ** np.arange(norm.size)  # (C, D+1)
    err_n = 4 * _EPS * norm.size * (mono @ np.abs(norm))
    err_x = 4 * _EPS * norm.size * np.einsum("cd,pkd->cpk", mono, np.abs(x_num))
    good = n0 > 1e6 * err_n  # the centre point is known to ~1e-6 relative or better
    n_safe = np.where(good, n0, 1.0)
    pts = tx[..., 0] / n_safe[:, None, None]
    # bound on the error of the evaluated points (numerator and norm errors)
    err_p = (np.linalg.norm(err_x, axis=-1).max(axis=-1)
             + np.abs(pts).max(axis=(1, 2)) * err_n) / (n_safe - np.where(good, err_n, 0.0))
    d = np.where(good, segment_distance(fixed[0], fixed[1], pts[:, 0], pts[:, 1]), np.inf)
    powers = r[:, None] ** np.arange(1, tn.shape[1])  # (C, D)
    cross = tx[..., 1:] * n0[:, None, None, None] - tx[..., :1] * tn[:, None, None, 1:]
    num = np.einsum("cpd,cd->cp", np.linalg.norm(cross, axis=2), powers).max(axis=1)
    n_lo = n0 - np.einsum("cd,cd->c", np.abs(tn[:, 1:]), powers)
    ok = good & (n_lo > 0)
    m = np.where(ok, num / np.where(ok, n0 * n_lo, 1.0), np.inf)
    # the centre distance may be off by the point error (and by segment_distance's round-off)
    slack = 2 * err_p + 1e-13 * (np.abs(pts).max(axis=(1, 2)) + np.abs(fixed).max())
    return d + np.where(good, err_p, 0.0), m + slack


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
