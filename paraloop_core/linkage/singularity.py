"""Singularity proximity of 6R loops over the motion cycle (paper Sec. 4.4, MATH section 9).

At parameter t the six loop axes ``A_0..A_5`` (unit spear coordinates ``(l, m)``, base frame,
as :func:`loops.axes_at`) form the rows of ``J(t)`` ``(6, 6)``; ``S(t)`` is the sum of the
squared 36 5x5 minors (= ``e_5(sigma_1^2..sigma_6^2)`` by Cauchy-Binet). ``S = 0`` iff the axes
lie in a linear congruence (singular configuration, or more than one DOF); spherical and planar
loops give ``S == 0``.

Frame and unit dependence: moments change with the frame origin and scale with the length
unit, so S does too (rotations about the origin leave it unchanged). S is computed in the frame
of the given joint factors (the world frame for factors of :func:`fourpose.world_motion`);
``length`` divides all moments by a design length for a unit-free measure, and a frame origin
near the loop avoids the bias of large moments.

Speed (the scan needs thousands of J per design): each axis is the quartic line polynomial
``L(t) A L~(t)`` (L the link motion carrying it, padded by the positive factor
``(1 + t^2)^k``, which leaves unit rows unchanged), so J(t) is one small contraction; the
minors are the components of the exterior products ``w_i`` of the five rows other than i
(prefix and suffix wedge products as vectorized gathers), so ``S = sum_i |w_i|^2`` with no
per-matrix LAPACK call (an SVD per matrix is several times slower). Each minor is a sum of
products of bounded entries, so the absolute error is about ``1e-15 (1 + max|m|)^5``, the same
order as ``e_5`` of singular values computed by an SVD.
"""

from __future__ import annotations

import itertools

import numpy as np

from paraloop_core.algebra import poly
from paraloop_core.tolerance import TOL

_PAD2 = np.array([1.0, 0.0, 2.0, 0.0, 1.0])  # (1 + t^2)^2, ascending
_LINE = np.array([0.0, 1, 1, 1, 0, 1, 1, 1])  # keeps the line part p + eps d of a factor
_SPEAR = [1, 2, 3, 5, 6, 7]
_GRID = 9  # points per zoom level (odd: the centre is kept)


def _check_factors(joint_factors: np.ndarray, length: float) -> np.ndarray:
    jf = np.asarray(joint_factors, dtype=np.float64)
    if jf.ndim < 2 or jf.shape[-2:] != (6, 8):
        raise ValueError(f"joint_factors must have shape (..., 6, 8), got {jf.shape}")
    if not np.all(np.isfinite(jf)):
        raise ValueError("joint_factors must be finite")
    pn = np.linalg.norm(jf[..., 1:4], axis=-1)
    if np.any(pn <= TOL.zero * (1.0 + np.abs(jf).max(axis=-1))):
        raise ValueError("a joint factor has no rotation axis (zero vector part)")
    if not (np.isfinite(length) and length > 0):
        raise ValueError(f"length must be a positive number, got {length!r}")
    return jf


def _axis_polys(jf: np.ndarray) -> np.ndarray:
    """Quartic line polynomials ``(..., 6, 5, 6)`` (spear components) whose unit rows are the
    axes at t."""
    lines = jf * _LINE
    lin = poly.linear(jf)
    one = np.stack([lin[..., 0, :, :], lin[..., 5, :, :]], axis=-3)  # t - a0, t - b0
    two = poly.mul(one, np.stack([lin[..., 1, :, :], lin[..., 4, :, :]], axis=-3))
    mid1 = poly.mul(poly.mul(one, lines[..., [1, 4], None, :]), poly.conj(one))
    mid2 = poly.mul(poly.mul(two, lines[..., [2, 3], None, :]), poly.conj(two))
    pad1 = np.zeros(mid2.shape)  # mid1 (1 + t^2)
    pad1[..., :3, :] += mid1
    pad1[..., 2:, :] += mid1
    ends = lines[..., [0, 5], None, :] * _PAD2[:, None]  # (1 + t^2)^2 A
    out = np.stack([ends[..., 0, :, :], pad1[..., 0, :, :], mid2[..., 0, :, :],
                    mid2[..., 1, :, :], pad1[..., 1, :, :], ends[..., 1, :, :]], axis=-3)
    return out[..., _SPEAR]


def _wedge_table(a: int, b: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wedge of grade a and grade b vectors of R^6 (basis: column subsets, lexicographic):
    output r is ``sum_k sign[r, k] x[ia[r, k]] y[ib[r, k]]`` (``C(a+b, a)`` terms each)."""
    sub_a = list(itertools.combinations(range(6), a))
    sub_b = list(itertools.combinations(range(6), b))
    out = {s: i for i, s in enumerate(itertools.combinations(range(6), a + b))}
    terms = [[] for _ in out]
    for i, x in enumerate(sub_a):
        for j, y in enumerate(sub_b):
            if set(x) & set(y):
                continue
            seq = x + y
            inversions = sum(seq[u] > seq[v] for u in range(len(seq))
                             for v in range(u + 1, len(seq)))
            terms[out[tuple(sorted(seq))]].append((i, j, -1.0 if inversions % 2 else 1.0))
    arr = np.array(terms)  # (n_out, C(a+b, a), 3)
    return arr[..., 0].astype(int), arr[..., 1].astype(int), arr[..., 2:]


_WEDGE = {(a, b): _wedge_table(a, b) for a in range(1, 5) for b in range(1, 6 - a)}


def _wedge(x: np.ndarray, a: int, y: np.ndarray, b: int) -> np.ndarray:
    """Wedge of grade-a ``x`` ``(C(6,a), B)`` and grade-b ``y`` (components first, so the
    gathers copy contiguous rows; elementwise only: no BLAS threading on tiny products)."""
    ia, ib, sign = _WEDGE[a, b]
    prod = x[ia]
    prod *= y[ib]
    prod *= sign
    return prod.sum(axis=1)


def minors_sq_sum(j: np.ndarray) -> np.ndarray:
    """Sum of the squared 5x5 minors ``(...)`` of matrices ``(..., 6, 6)``.

    ``= sum_i |w_i|^2`` with ``w_i`` the wedge of all rows but i. Only squared norms are
    needed, so factors may be wedged in any order (signs drop out); prefix chains
    ``r0 ^ r1 ^ ...`` and suffix chains ``r5 ^ r4 ^ ...`` are stacked to share each call.
    Matrices go in chunks of :data:`_CHUNK` (small temporaries stay in cache: several times
    faster than one big batch).
    """
    j = np.asarray(j, dtype=np.float64)
    flat = j.reshape(-1, 6, 6)
    out = np.concatenate([_minors_chunk(flat[k : k + _CHUNK])
                          for k in range(0, max(len(flat), 1), _CHUNK)])
    return out.reshape(j.shape[:-2])


_CHUNK = 128


def _minors_chunk(j: np.ndarray) -> np.ndarray:
    nb = len(j)
    r = np.moveaxis(j, 0, -1)  # (6 rows, 6 cols, B)
    cat = np.concatenate
    p2s2 = _wedge(cat([r[0], r[5]], -1), 1, cat([r[1], r[4]], -1), 1)  # r0^r1 | r5^r4
    p3s3 = _wedge(p2s2, 2, cat([r[2], r[3]], -1), 1)  # r0^r1^r2 | r5^r4^r3
    p4s4 = _wedge(p3s3, 3, cat([r[3], r[2]], -1), 1)  # r0^..^r3 | r5^..^r2
    p4, s4 = p4s4[:, :nb], p4s4[:, nb:]
    # grade 4 ^ grade 1: w_5 = p4^r4, w_0 = s4^r1, w_1 = s4^r0, w_4 = p4^r5
    w5014 = _wedge(cat([p4, s4, s4, p4], -1), 4, cat([r[4], r[1], r[0], r[5]], -1), 1)
    # grade 2 ^ grade 3: w_2 = (r0^r1)^(r5^r4^r3), w_3 = (r5^r4)^(r0^r1^r2)
    w23 = _wedge(p2s2, 2, cat([p3s3[:, nb:], p3s3[:, :nb]], -1), 3)
    return np.sum(w5014**2, 0).reshape(4, nb).sum(0) + np.sum(w23**2, 0).reshape(2, nb).sum(0)


def _curve(spear_polys: np.ndarray, s: np.ndarray, c: np.ndarray, length: float) -> np.ndarray:
    """S ``(..., T)`` at ``t = s / c`` (``s, c`` broadcasting as ``(..., T)`` or ``(T,)``).

    The quartic rows are evaluated homogeneously, ``c^4 L(s / c) = sum_k L_k s^k c^(4-k)``:
    no overflow, and ``c = 0`` (t = inf) gives the leading coefficient.
    """
    k = np.arange(5)
    basis = s[..., None] ** k * c[..., None] ** (4 - k)  # (..., T, 5)
    flat = spear_polys.swapaxes(-3, -2).reshape(spear_polys.shape[:-3] + (5, 36))
    rows = basis @ flat
    rows = rows.reshape(rows.shape[:-1] + (6, 6))
    dirs = rows[..., :3]
    rows = rows / np.sqrt(np.einsum("...i,...i->...", dirs, dirs))[..., None]
    if length != 1.0:
        rows[..., 3:] /= length
    return minors_sq_sum(rows)


def _angle(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(sin, cos)`` of ``pi (u - 1/2)``, so that ``t = poly.param_to_t(u) = sin / cos``."""
    theta = np.pi * (u - 0.5)
    return np.sin(theta), np.cos(theta)


def singularity_curve(joint_factors: np.ndarray, t: np.ndarray,
                      length: float = 1.0) -> np.ndarray:
    """``S(t)`` ``(..., T)`` of loops ``joint_factors`` ``(..., 6, 8)`` at ``t`` ``(T,)``, or
    per loop ``(..., T)`` (broadcasting); inf = home configuration. Moments are divided by
    ``length``."""
    jf = _check_factors(joint_factors, length)
    t = np.asarray(t, dtype=np.float64)
    if t.ndim < 1 or np.any(np.isnan(t)):
        raise ValueError(f"t must be an array (T,) or (..., T) without NaN, got {t.shape}")
    inf = np.isinf(t)
    r = np.hypot(np.where(inf, 1.0, t), 1.0)
    s, c = np.where(inf, 1.0, t / r), np.where(inf, 0.0, 1.0 / r)
    return _curve(_axis_polys(jf), s, c, float(length))


def _cycle_samples(jf: np.ndarray, per_factor: int) -> np.ndarray:
    """Sorted ``u`` ``(..., 3 per_factor + 1)`` in ``[0, 1)`` adapted to the motion: for each
    of the first three joint factors (in a loop of a cubic: one per norm factor
    ``(t - h0)^2 + r^2``)
    the t where its rotation angle is uniform, ``t = h0 + r cot(pi (j + 1/2) / k)``, and
    ``u = 0`` (t = inf). Fast parts of the cycle (small r) get their share of samples."""
    t = poly.cycle_parameters(jf[..., :3, 0], np.linalg.norm(jf[..., :3, 1:4], axis=-1),
                              per_factor)
    u = poly.t_to_param(t)
    return np.sort(np.concatenate([np.zeros(u.shape[:-1] + (1,)), u], axis=-1), axis=-1)


def singularity_min(joint_factors: np.ndarray, samples: int = 24, levels: int = 3,
                    basins: int = 3, length: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """``(min S, t at the min)`` ``(...)`` over the whole cycle ``R u {inf}`` of each loop.

    Scan at ``3 samples + 1`` parameters adapted to the motion (:func:`_cycle_samples`); the
    ``basins`` lowest sampled local minima of every loop are refined together, all loops at
    once, by ``levels`` zoom levels of 9 points in ``u`` (:func:`poly.param_to_t`), starting
    from the bracket of the neighbouring samples and shrinking 4x per level, then one parabola
    step through the last grid's minimum. A basin narrower than the sample spacing whose
    sampled values are not among the ``basins`` lowest can be missed. Accuracy of the defaults
    on 43 random cubics x 9 loops against 100001 uniform samples: relative error <= 1e-3 in
    386 of 387 loops; one sharp dip was missed by 37 %, i.e. 3e-3 times the median of S over
    the cycle (raise ``samples``/``basins`` for more safety). t is inf where the minimum is at
    home.
    """
    jf = _check_factors(joint_factors, length)
    if not all(isinstance(v, int) for v in (samples, levels, basins)) or samples < 4 \
            or levels < 0 or not 1 <= basins <= samples:
        raise ValueError("samples (>= 4), levels (>= 0) and basins (1..samples) must be ints")
    ap = _axis_polys(jf)
    u = _cycle_samples(jf, samples)  # (..., n)
    vals = _curve(ap, *_angle(u), float(length))
    local = (vals <= np.roll(vals, 1, -1)) & (vals <= np.roll(vals, -1, -1))
    j = np.argsort(np.where(local, vals, np.inf), axis=-1)[..., :basins]
    wrapped = np.concatenate([u[..., -1:] - 1.0, u, u[..., :1] + 1.0], axis=-1)
    lo = np.take_along_axis(wrapped, j, -1)  # neighbours of sample j (periodic in u)
    hi = np.take_along_axis(wrapped, j + 2, -1)
    best_u, best_v = np.take_along_axis(u, j, -1), np.take_along_axis(vals, j, -1)
    ap = ap[..., None, :, :, :]  # basin axis
    grid = lo[..., None] + (hi - lo)[..., None] * np.linspace(0.0, 1.0, _GRID)
    for _ in range(levels):
        gv = _curve(ap, *_angle(grid), float(length))
        i = np.argmin(gv, axis=-1)[..., None]
        v = np.take_along_axis(gv, i, -1)[..., 0]
        better = v < best_v
        best_u = np.where(better, np.take_along_axis(grid, i, -1)[..., 0], best_u)
        best_v = np.where(better, v, best_v)
        evaluated, step = grid, grid[..., 1] - grid[..., 0]
        grid = best_u[..., None] + step[..., None] * np.linspace(-1.0, 1.0, _GRID)
    if levels:  # one parabola step through the last grid's minimum and its neighbours
        i = np.clip(np.argmin(gv, axis=-1), 1, _GRID - 2)[..., None]
        f0, f1, f2 = (np.take_along_axis(gv, i + d, -1)[..., 0] for d in (-1, 0, 1))
        curv = f0 - 2.0 * f1 + f2
        shift = np.where(curv > 0, 0.5 * (f0 - f2) / np.where(curv > 0, curv, 1.0), 0.0)
        x = np.take_along_axis(evaluated, i, -1)[..., 0] + np.clip(shift, -1.0, 1.0) * step
        fx = _curve(ap, *_angle(x[..., None]), float(length))[..., 0]
        best_u, best_v = np.where(fx < best_v, x, best_u), np.minimum(fx, best_v)
    k = np.argmin(best_v, axis=-1)[..., None]
    return (np.take_along_axis(best_v, k, -1)[..., 0],
            poly.param_to_t(np.take_along_axis(best_u, k, -1)[..., 0]))
