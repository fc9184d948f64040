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


def _dyadic(x: float) -> tuple[int, int]:
    """``(m, e)`` with ``x = m 2^e`` exactly (a float is a dyadic rational)."""
    f = Fraction(x)
    return f.numerator, -(f.denominator.bit_length() - 1)


def _to_float(m: int, e: int) -> float:
    """``|m| 2^e`` as a float, rounded up (a hair: the result bounds the exact value)."""
    m = abs(m)
    cut = max(m.bit_length() - 60, 0)  # keep 60 bits: truncation < 2^-59 relative
    x = math.ldexp(float(m >> cut), e + cut) * (1.0 + 2.0**-50)
    return x if x > 1e-300 or not m else 1e-300  # never round a defect down to nothing


def _exact_defect(joint_factors: np.ndarray) -> tuple[list[list[int]], int]:
    """Exact coefficients (ascending) of ``vec(P)`` and ``Q`` of ``Pi(t)`` for the float
    factors ``(6, 8)``, from their binary values: ``(ints (7 x 7), e)``, value ``int 2^e``."""
    lin = loops.joint_polys(np.asarray(joint_factors, dtype=np.float64))  # (6, 2, 8)
    dy = [[[_dyadic(float(x)) for x in c] for c in f] for f in lin]
    e = min(ex for f in dy for c in f for _, ex in c)  # every value an int times 2^e
    ints = [[[m << (ex - e) for m, ex in c] for c in f] for f in dy]
    prod = ints[0]
    for g in ints[1:]:  # ascending coefficient lists of 8-int lists
        out = [[0] * 8 for _ in range(len(prod) + 1)]
        for i, a in enumerate(prod):
            for j, b in enumerate(g):
                out[i + j] = [x + y for x, y in zip(out[i + j], _dqmul(a, b), strict=True)]
        prod = out
    return [c[1:] for c in prod], 6 * e


def _in_chart(coeffs: tuple[list[list[int]], int], alpha: float, beta: float) -> np.ndarray:
    """``(7, 2)`` norms (rounded up) of the vec(P) and Q coefficients of ``Pi(alpha s + beta)``
    in s: exact substitution, so a chart that centres the norm roots keeps the sums tight."""
    ints, e = coeffs
    (am, ae), (bm, be) = _dyadic(alpha), _dyadic(beta)
    n = len(ints)
    out = np.empty((n, 2))
    for k in range(n):  # coefficient of s^k: sum_j c_j C(j, k) beta^(j-k) alpha^k
        # beta^(j-k) = bm^(j-k) 2^(be (j-k)): bring every term to 2^(be (n-1-k))
        terms = [(math.comb(j, k) * bm ** (j - k)) << (-be * (n - 1 - j)) if be <= 0 else
                 (math.comb(j, k) * bm ** (j - k)) << (be * (j - k)) for j in range(k, n)]
        shift = e + k * ae + (be * (n - 1 - k) if be <= 0 else 0)
        col = [am**k * sum(t * ints[j][m] for t, j in zip(terms, range(k, n), strict=True))
               for m in range(7)]
        out[k] = [math.hypot(*(_to_float(c, shift) for c in col[:3])),
                  math.hypot(*(_to_float(c, shift) for c in col[3:]))]
    return out * (1.0 + 2.0**-48)  # hypot rounds too: a hair up


def reading_gap(joint_factors: np.ndarray) -> tuple[float, float]:
    """``(rot, shift)``: the two readings of the loop ``(6, 8)`` place a point y at most
    ``rot |y| + shift`` apart over ``R u {inf}`` (proven; the module docstring's ``e(t)``
    with the sups of its two terms taken apart)."""
    jf = np.asarray(joint_factors, dtype=np.float64)
    exact = _exact_defect(jf)
    a = jf[:, 0]
    b = np.linalg.norm(jf[:, 1:4], axis=1)
    if any(exact[0][6]) or not (np.isfinite(a).all() and (b > 0).all()):
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
