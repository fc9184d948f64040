"""High-precision arithmetic (mpmath) to confirm a degeneracy before a refusal.

Float64 cannot tell a truly real or repeated norm root from a legitimate but extreme
configuration (roots at hyperbolic distance ~25 look like a real root split by round-off), so
:func:`factor.all_factorizations` only *suspects* non-genericity in float64 and asks this module.
The input coefficients are taken as exact; at ``DIGITS`` decimal digits a real double root splits
by ~10^-(DIGITS/2) and a repeated one by less, far below the thresholds used here, while every
configuration float64 could produce stays far above them. Scalar Python on 8-lists: slow
(milliseconds) but only run for suspects, and the common case (a generic motion float64 was
unsure of) is confirmed by polishing float64's roots (:func:`_polished`).
"""

from __future__ import annotations

import itertools

import mpmath
import numpy as np

#: Working precision (decimal digits) of the confirmation.
DIGITS = 60
#: Newton steps allowed to polish a float64 norm root (:func:`_polished`).
NEWTON_STEPS = 12
#: ``cosh(d) - 1`` of two norm roots above which one of them counts as truly real.
REAL_SEPARATION = mpmath.mpf(10) ** 24
#: ``sinh(d / 2)`` below which two norm roots count as truly repeated.
REPEATED_GAP = mpmath.mpf(10) ** -20
#: relative size below which a remainder's leading primal part counts as truly zero.
SINGULAR = mpmath.mpf(10) ** -30

_Q = {(0, 0): (0, 1), (0, 1): (1, 1), (0, 2): (2, 1), (0, 3): (3, 1),
      (1, 0): (1, 1), (1, 1): (0, -1), (1, 2): (3, 1), (1, 3): (2, -1),
      (2, 0): (2, 1), (2, 1): (3, -1), (2, 2): (0, -1), (2, 3): (1, 1),
      (3, 0): (3, 1), (3, 1): (2, 1), (3, 2): (1, -1), (3, 3): (0, -1)}


def _qmul(a: list, b: list) -> list:
    out = [mpmath.mpf(0)] * 4
    for (j, k), (i, s) in _Q.items():
        out[i] += s * a[j] * b[k]
    return out


def _mul(a: list, b: list) -> list:
    """Dual-quaternion product of 8-lists (convention of :mod:`paraloop_core.algebra.dq`)."""
    pd = _qmul(a[:4], b[4:])
    dp = _qmul(a[4:], b[:4])
    return _qmul(a[:4], b[:4]) + [x + y for x, y in zip(pd, dp, strict=True)]


def _conj(a: list) -> list:
    return [a[0], -a[1], -a[2], -a[3], a[4], -a[5], -a[6], -a[7]]


def _inv(a: list) -> list:
    n = sum(x * x for x in a[:4])
    pinv = [x / n for x in _conj(a)[:4]]
    d = _qmul(_qmul(pinv, a[4:]), pinv)
    return pinv + [-x for x in d]


def _poly(c: np.ndarray) -> list:
    return [[mpmath.mpf(float(x)) for x in row] for row in np.asarray(c, dtype=np.float64)]


def _norm(c: list) -> list:
    """Coefficients (ascending) of the norm polynomial ``|P(t)|^2`` of ``c``."""
    n = len(c) - 1
    norm = [mpmath.mpf(0)] * (2 * n + 1)
    for i, j in itertools.product(range(n + 1), repeat=2):
        norm[i + j] += sum(c[i][k] * c[j][k] for k in range(4))
    return norm


def _norm_roots(norm: list) -> list:
    """Upper-half-plane roots of the norm polynomial (coefficients ``norm``, ascending)."""
    # Companion-matrix eigenvalues (QR): unlike polyroots' iteration they also converge on the
    # multiple roots whose presence is the question.
    d = len(norm) - 1
    comp = mpmath.zeros(d, d)
    for i in range(1, d):
        comp[i, i - 1] = 1
    for i in range(d):
        comp[i, d - 1] = -norm[i] / norm[d]
    roots = mpmath.eig(comp, left=False, right=False)
    return sorted(roots, key=lambda z: -mpmath.im(z))[:d // 2]


def _polished(norm: list, hints: np.ndarray) -> list | None:
    """The roots near the float64 ``hints`` polished by Newton's method, or None where one
    does not converge within :data:`NEWTON_STEPS` (quadratic convergence takes a simple root
    from float64 to ``DIGITS`` in about four; a root near a multiple one converges slowly, and
    the companion matrix decides)."""
    coeffs = norm[::-1]
    tol = mpmath.mpf(10) ** (8 - DIGITS)
    out = []
    for h in np.asarray(hints, complex):
        z = mpmath.mpc(float(h.real), float(h.imag))
        for _ in range(NEWTON_STEPS):
            f, df = mpmath.polyval(coeffs, z, derivative=True)
            if df == 0:
                return None
            step = f / df
            z -= step
            if abs(step) <= tol * (1 + abs(z)):
                break
        else:
            return None
        out.append(z)
    return out


def _code(z: list) -> int:
    """0 generic, 1 real root, 2 repeated quadratic factor (codes of ``factor.REASONS``)."""
    if any(mpmath.im(w) <= 0 for w in z):
        return 1
    for a, b in itertools.combinations(z, 2):
        sep = abs(a - b) ** 2 / (2 * mpmath.im(a) * mpmath.im(b))
        if sep >= REAL_SEPARATION:
            return 1
        if mpmath.sqrt(sep / 2) <= REPEATED_GAP:
            return 2
    return 0


def _mod_quadratic(c: list, m0: mpmath.mpf, m1: mpmath.mpf) -> tuple[list, list]:
    rem = [row[:] for row in c]
    for k in range(len(c) - 1, 1, -1):
        lead = rem[k]
        rem[k - 1] = [x - m1 * y for x, y in zip(rem[k - 1], lead, strict=True)]
        rem[k - 2] = [x - m0 * y for x, y in zip(rem[k - 2], lead, strict=True)]
    return rem[0], rem[1]


def _right_quotient(c: list, h: list) -> list:
    """``Q`` with ``C = Q (t - h) + r``."""
    n = len(c) - 1
    q = [None] * n
    q[n - 1] = c[n]
    for k in range(n - 1, 0, -1):
        q[k - 1] = [x + y for x, y in zip(c[k], _mul(q[k], h), strict=True)]
    return q


def _flip(h1: list, h2: list) -> tuple[list, list] | None:
    x = [a - b for a, b in zip(_conj(h1), h2, strict=True)]
    size = max(abs(v) for v in h1 + h2) + 1
    if mpmath.sqrt(sum(v * v for v in x[:4])) <= SINGULAR * size:
        return None
    k2 = _mul(_mul(_inv(x), h1), x)
    return [a + b - c for a, b, c in zip(h1, h2, k2, strict=True)], k2


def factorizations(c_monic: np.ndarray, flip_plan: tuple, hints: np.ndarray | None = None
                   ) -> tuple[np.ndarray | None, np.ndarray | None, int]:
    """All factorizations of a monic cubic ``(4, 8)`` in ``DIGITS``-digit arithmetic.

    Returns ``(factors (6, 3, 8), quadratics (3, 2), code)`` as float64 with the labelling and
    flip plan of :mod:`factor`, or ``(None, None, code)`` with the confirmed reason code
    (1 real root, 2 repeated factor, 3 singular remainder / flip) when truly degenerate.
    ``hints`` ``(3,)``: float64 upper norm roots, polished by Newton's method; where they
    converge to three distinct upper roots, generic at ``DIGITS`` (they and their conjugates
    are then all six roots: none real, none repeated), those are the roots (40 times faster
    than the companion matrix); anything else, every refusal included, is decided by the
    companion matrix.
    """
    with mpmath.workdps(DIGITS):
        c = _poly(c_monic)
        norm = _norm(c)
        z = None if hints is None else _polished(norm, hints)
        if z is None or _code(z):
            z = _norm_roots(norm)
        code = _code(z)
        if code:
            return None, None, code
        quads = sorted(((abs(w) ** 2, -2 * mpmath.re(w)) for w in z),
                       key=lambda m: (m[0], m[1]))
        size = max(abs(v) for row in c for v in row)
        hs: list = [None] * 3
        cur = c
        for i in range(2, -1, -1):
            r0, r1 = _mod_quadratic(cur, *quads[i])
            if mpmath.sqrt(sum(v * v for v in r1[:4])) <= SINGULAR * size:
                return None, None, 3
            h = [-v for v in _mul(_inv(r1), r0)]
            h[4] = mpmath.mpf(0)
            hs[i] = h
            cur = _right_quotient(cur, h)
        out: list = [None] * 6
        out[0] = hs
        for src, pos, dst in flip_plan:
            f = list(out[src])
            flipped = _flip(f[pos], f[pos + 1])
            if flipped is None:
                return None, None, 3
            f[pos], f[pos + 1] = flipped
            out[dst] = f
        factors = np.array([[[float(v) for v in h] for h in f] for f in out])
        return factors, np.array([[float(m0), float(m1)] for m0, m1 in quads]), 0
