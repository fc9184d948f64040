"""How far the two readings of a float64 loop disagree: a proven bound, for the certificate.

The loop's joint factors are float64 numbers, so the loop closes only approximately: the
motion of link j relative to link i read one way round the loop (:func:`loops.relative_chain`,
what the certificate bounds) and read the other way differ. In exact arithmetic the product
of all six forward factors ``Pi(t) = T_0(t) ... T_5(t)`` (:func:`loops.joint_polys`) is a real
polynomial; of the float factors it is ``Pi = P + eps Q`` with a small non-real part
``v = vec(P)`` and ``Q``. Any pair's two readings differ by a conjugate of ``Pi`` acting on a
point y of norm <= R (rigid conjugations keep distances), which moves y by at most

    ``e(t) = (4 R |v(t)| + 2 |Q(t)|) / |P(t)|``

(rotation by ``P / |P|``, at most ``2 |v| / |P|`` from +-1 as a unit quaternion, moves y by
twice that times ``|y|``; the translation is ``2 |Q| / |P|`` at most). Near a fast turn
(a norm root close to the real axis) ``|P|`` is tiny and a last-bit error of the factors shows
at ``1e-6`` of the size: random design 20695 (S = 3e-10) reads its pins 3.9e-6 apart.

The defect ``v, Q`` is computed exactly (integer arithmetic on the float factors' binary
values), ``|P(t)| = prod_m |t - h_m|`` from the factors' norms (quaternion norms multiply);
the sup over the projective line is bounded on cells (monotone numerator, each norm
quadratic's least value on the cell) and a tail bound. The certificate subtracts
:func:`reading_gap` from every proven lower bound, so it holds for either reading.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from paraloop_core.linkage import loops
from paraloop_core.realization.clearance import charts

#: Relative allowance on the float evaluation of the cell bounds (a few roundings of
#: products of at most twelve factors).
_SLACK = 1e-12


def _qmul(a: list, b: list) -> list:
    """Exact quaternion product of two wxyz lists of Python ints."""
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    return [a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3, a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1, a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0]


def _dqmul(a: list, b: list) -> list:
    pa, da, pb, db = a[:4], a[4:], b[:4], b[4:]
    return _qmul(pa, pb) + [x + y for x, y in zip(_qmul(pa, db), _qmul(da, pb), strict=True)]


def _exact_defect(joint_factors: np.ndarray) -> list[list[Fraction]]:
    """Exact coefficients (ascending) of ``vec(P)`` and ``Q`` of ``Pi(t)`` (7 x 7 Fractions)
    for the float factors ``(6, 8)``, from their binary values in integer arithmetic."""
    lin = loops.joint_polys(np.asarray(joint_factors, dtype=np.float64))  # (6, 2, 8)
    fr = [[[Fraction(float(x)) for x in c] for c in f] for f in lin]
    den = max(x.denominator for f in fr for c in f for x in c)  # a power of two
    prod = [[int(x * den) for x in c] for c in fr[0]]
    for f in fr[1:]:  # ascending coefficient lists of 8-int lists
        g = [[int(x * den) for x in c] for c in f]
        out = [[0] * 8 for _ in range(len(prod) + 1)]
        for i, a in enumerate(prod):
            for j, b in enumerate(g):
                out[i + j] = [x + y for x, y in zip(out[i + j], _dqmul(a, b), strict=True)]
        prod = out
    scale = Fraction(1, den**6)
    return [[c[k] * scale for k in range(1, 8)] for c in prod]


def _in_chart(coeffs: list[list[Fraction]], alpha: float, beta: float) -> np.ndarray:
    """``(7, 2)`` norms (rounded up) of the vec(P) and Q coefficients of ``Pi(alpha s + beta)``
    in s: exact substitution, so a chart that centres the norm roots keeps the sums tight."""
    al, be = Fraction(alpha), Fraction(beta)
    n = len(coeffs)
    out = []
    for k in range(n):  # coefficient of s^k: sum_j c_j C(j, k) beta^(j-k) alpha^k
        col = [sum((coeffs[j][m] * math.comb(j, k) * be ** (j - k) for j in range(k, n)),
                   Fraction(0)) * al**k for m in range(7)]
        out.append([math.hypot(*(float(x) for x in col[:3])),
                    math.hypot(*(float(x) for x in col[3:]))])
    return np.array(out) * (1.0 + 2.0**-48)  # float() rounds to nearest: a hair up


def reading_gap(joint_factors: np.ndarray) -> tuple[float, float]:
    """``(rot, shift)``: the two readings of the loop ``(6, 8)`` place a point y at most
    ``rot |y| + shift`` apart over ``R u {inf}`` (proven; the module docstring's ``e(t)``
    with the sups of its two terms taken apart)."""
    jf = np.asarray(joint_factors, dtype=np.float64)
    exact = _exact_defect(jf)
    a = jf[:, 0]
    b = np.linalg.norm(jf[:, 1:4], axis=1)
    if any(exact[6]) or not (np.isfinite(a).all() and (b > 0).all()):
        return float("inf"), float("inf")  # the leading coefficients are 1: no defect there
    (alpha, beta), extra = charts(jf)
    maps = [(1.0, 0.0), (alpha, beta), *extra]
    nums = [_in_chart(exact, *m) * [4.0, 2.0] for m in maps]  # (7, 2): |v|, |Q| coefficients
    big = 2.0 * float(np.abs(a).max()) + 4.0 * float(b.max()) + 1.0
    # cells: a fine grid about every norm root (width ~ b_m) and a coarse one over [-big, big]
    g = np.concatenate([[0.0], 0.05 * 1.1 ** np.arange(300)])  # out to 1e11 b_m
    near = (a[:, None] + b[:, None] * np.concatenate([-g, g])[None, :]).ravel()
    edges = np.unique(np.clip(np.concatenate([near, np.linspace(-big, big, 4097)]), -big, big))
    lo, hi = edges[:-1], edges[1:]
    top = np.full((len(lo), 2), np.inf)  # |v|, |Q| <= sum |c_k| |s|^k, the best chart
    for (al, be), num in zip(maps, nums, strict=True):
        smax = np.maximum(np.abs(lo - be), np.abs(hi - be)) / abs(al)
        top = np.minimum(top, np.polynomial.polynomial.polyval(smax, num).T)
    # least of (t - a_m)^2 + b_m^2 on [lo, hi]: at a_m inside, else at the nearer end
    gap = np.clip(a[None, :], lo[:, None], hi[:, None]) - a[None, :]
    bottom = np.sqrt(np.prod(gap**2 + b[None, :] ** 2, axis=1))
    inner = (top / bottom[:, None]).max(axis=0)
    # |t| >= big >= 2 |a_m|: (t - a_m)^2 >= t^2 / 4, so |P| >= |t|^6 / 8, and the numerators
    # (degree <= 5 in t) over |t|^6 fall with |t|
    tail = 8.0 * np.polynomial.polynomial.polyval(big, nums[0]) / big**6
    rot, shift = np.maximum(inner, tail) * (1.0 + _SLACK)
    return float(rot), float(shift)
