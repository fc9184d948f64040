"""Motion polynomials: dual-quaternion polynomials as arrays ``(..., n+1, 8)``.

Coefficient axis is second to last, **ascending powers** (index k multiplies ``t**k``); the
parameter t is real and central. Dual-quaternion layout as in :mod:`paraloop_core.algebra.dq`.
The projective parameter line ``R u {inf}`` is sampled by ``u in [0, 1]`` via
:func:`param_to_t` (``u = 0`` and ``u = 1`` both give ``t = inf``).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from paraloop_core.algebra import dq


def as_poly(c: np.ndarray, name: str = "polynomial") -> np.ndarray:
    """Validate and return a float64 polynomial array ``(..., n+1, 8)``."""
    c = np.asarray(c, dtype=np.float64)
    if c.ndim < 2 or c.shape[-1] != 8:
        raise ValueError(f"{name} must have shape (..., n+1, 8), got {c.shape}")
    if not np.isfinite(c).all():
        raise ValueError(f"{name} has non-finite coefficients")
    return c


def mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Product ``A(t) B(t)``: ``(..., m+1, 8) x (..., n+1, 8) -> (..., m+n+1, 8)``."""
    m, n = a.shape[-2] - 1, b.shape[-2] - 1
    prod = dq.mul(a[..., :, None, :], b[..., None, :, :])  # (..., m+1, n+1, 8)
    out = np.zeros(np.broadcast_shapes(a.shape[:-2], b.shape[:-2]) + (m + n + 1, 8))
    for i in range(m + 1):  # loop over the (tiny) degree, not over data
        out[..., i : i + n + 1, :] += prod[..., i, :, :]
    return out


def conj(c: np.ndarray) -> np.ndarray:
    """Conjugate polynomial ``C~`` (coefficientwise)."""
    return dq.conj(c)


def linear(h: np.ndarray) -> np.ndarray:
    """The linear polynomial ``t - h`` ``(..., 2, 8)`` for ``h`` ``(..., 8)``."""
    h = np.asarray(h, dtype=np.float64)
    out = np.empty(h.shape[:-1] + (2, 8))
    np.negative(h, out=out[..., 0, :])
    out[..., 1, :] = dq.IDENTITY
    return out


def from_factors(h: np.ndarray) -> np.ndarray:
    """``(t - h_0)(t - h_1)...(t - h_{n-1})`` for ``h`` ``(..., n, 8)`` -> ``(..., n+1, 8)``."""
    h = np.asarray(h, dtype=np.float64)
    out = linear(h[..., 0, :])
    for i in range(1, h.shape[-2]):
        out = mul(out, linear(h[..., i, :]))
    return out


def evaluate(c: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Exact value ``C(t)`` ``(..., 8)``; ``t`` broadcasts against the batch shape ``(...)``.

    At ``t = +-inf`` the leading coefficient is returned (the pose there, up to scale).
    """
    t = np.asarray(t, dtype=np.float64)
    inf = np.isinf(t)
    tf = np.where(inf, 0.0, t)[..., None]
    out = c[..., -1, :]
    for k in range(c.shape[-2] - 2, -1, -1):
        out = out * tf + c[..., k, :]
    return np.where(inf[..., None], c[..., -1, :], out)


def evaluate_pose(c: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Homogeneous pose ``C(t) / max(1, |t|)**n`` ``(..., 8)``: overflow-free, exact at inf.

    For ``|t| > 1`` the reversed polynomial is evaluated at ``1/t`` (same pose, scaled).
    """
    return evaluate_scaled(c, t, 1)


def evaluate_scaled(c: np.ndarray, t: np.ndarray, trailing: int) -> np.ndarray:
    """``C(t) / max(1, |t|)**n`` ``(..., *trail)`` of polynomials ``c`` ``(..., n+1, *trail)``
    with ``trailing`` axes after the (ascending) coefficient axis; ``t`` broadcasts against the
    batch shape ``(...)``. Horner in t for ``|t| <= 1``, else in ``1/t`` over the reversed
    coefficients: overflow-free, and ``t = +-inf`` gives the leading coefficient."""
    t = np.asarray(t, dtype=np.float64)
    big = np.abs(t) > 1.0
    s = np.where(big, 1.0 / np.where(big, t, 1.0), t)  # 1/inf -> 0
    s = s.reshape(s.shape + (1,) * trailing)
    coef = np.moveaxis(c, c.ndim - 1 - trailing, 0)
    n = coef.shape[0] - 1
    lo, hi = coef[n], coef[0]
    for k in range(n - 1, -1, -1):  # loop over the (tiny) degree, not over data
        lo = lo * s + coef[k]
        hi = hi * s + coef[n - k]
    return np.where(big.reshape(s.shape), hi, lo)


def param_to_t(u: np.ndarray) -> np.ndarray:
    """Map ``u in [0, 1]`` onto the projective line: ``t = tan(pi (u - 1/2))``, inf at 0 and 1."""
    u = np.asarray(u, dtype=np.float64)
    t = np.tan(np.pi * (u - 0.5))
    edge = np.abs(u % 1.0) <= 1e-15
    return np.where(edge, np.inf, t)


def t_to_param(t: np.ndarray) -> np.ndarray:
    """Inverse of :func:`param_to_t` into ``(0, 1)``; ``inf`` maps to 0."""
    t = np.asarray(t, dtype=np.float64)
    return np.where(np.isinf(t), 0.0, np.arctan(t) / np.pi + 0.5)


def cycle_parameters(h0: np.ndarray, r: np.ndarray, per_factor: int) -> np.ndarray:
    """Sorted parameters ``(..., n per_factor)`` adapted to a motion with norm factors
    ``(t - h0)^2 + r^2`` (``h0``, ``r`` ``(..., n)``): where each factor's rotation angle is
    uniform, ``t = h0 + r cot(pi (j + 1/2) / per_factor)``. Uniform samples in u miss the fast
    parts of a cycle (a factor with small r turns fully within ``|t - h0| ~ r``)."""
    t = h0[..., None] + r[..., None] / np.tan(np.pi * (np.arange(per_factor) + 0.5) / per_factor)
    return np.sort(t.reshape(t.shape[:-2] + (-1,)), axis=-1)


def norm_poly(c: np.ndarray) -> np.ndarray:
    """Norm polynomial ``N = C C~`` (its real part) ``(..., 2n+1)``, ascending."""
    p = c[..., :4]
    n = c.shape[-2] - 1
    out = np.zeros(c.shape[:-2] + (2 * n + 1,))
    pp = np.einsum("...il,...jl->...ij", p, p)
    for i in range(n + 1):
        out[..., i : i + n + 1] += pp[..., i, :]
    return out


def study_poly(c: np.ndarray) -> np.ndarray:
    """``sum_l P_l D_l`` as a polynomial ``(..., 2n+1)``; identically 0 iff C is a motion poly."""
    n = c.shape[-2] - 1
    pd = np.einsum("...il,...jl->...ij", c[..., :4], c[..., 4:])
    out = np.zeros(c.shape[:-2] + (2 * n + 1,))
    for i in range(n + 1):
        out[..., i : i + n + 1] += pd[..., i, :]
    return out


def is_motion_polynomial(c: np.ndarray, rtol: float = 1e-9) -> np.ndarray:
    """Mask ``(...)``: the Study polynomial vanishes relative to the coefficient size."""
    scale = np.abs(c).max(axis=(-2, -1)) ** 2
    return np.abs(study_poly(c)).max(axis=-1) <= rtol * np.maximum(scale, 1e-300)


def make_monic(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(monic, lead)`` with ``C = lead * monic``; raises if the leading coefficient's
    primal part is exactly zero or the division overflows.

    A *small* leading coefficient is no test at all: it depends on the unit of t (``C(lambda
    t)`` scales coefficient k by ``lambda^k``; a monic cubic with coefficients 1e12 was refused).
    A motion nearly undefined at t = inf has a norm root near infinity, i.e. at a large
    hyperbolic distance from the others, which the unit-free genericity test of
    :mod:`factor` catches (and confirms in high precision)."""
    c = as_poly(c)
    lead = c[..., -1, :]
    pn = np.sqrt((lead[..., :4] ** 2).sum(-1))
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        monic = dq.mul(dq.inv(lead)[..., None, :], c) if (pn > 0).all() else None
    if monic is None or not np.isfinite(monic).all():
        raise ValueError(
            "leading coefficient has zero primal part (the motion is not defined at t = inf); "
            "reparametrize the motion first"
        )
    return monic, lead


def right_divide_linear(c: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``C = Q (t - h) + r``: returns ``(Q (..., n, 8), r (..., 8))`` with the right value
    ``r = C(h)``."""
    n = c.shape[-2] - 1
    q = np.empty(np.broadcast_shapes(c.shape[:-2], h.shape[:-1]) + (n, 8))
    q[..., n - 1, :] = c[..., n, :]
    for k in range(n - 1, 0, -1):
        q[..., k - 1, :] = c[..., k, :] + dq.mul(q[..., k, :], h)
    r = c[..., 0, :] + dq.mul(q[..., 0, :], h)
    return q, r


def mod_quadratic(c: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Remainder ``(..., 2, 8)`` of ``C`` modulo ``t^2 + m1 t + m0``, ``m`` ``(..., 2)=[m0, m1]``.

    M is real hence central, so left and right remainders agree.
    """
    m0 = m[..., 0, None]
    m1 = m[..., 1, None]
    rem = c.copy()
    for k in range(c.shape[-2] - 1, 1, -1):
        lead = rem[..., k, :]
        rem[..., k - 1, :] -= m1 * lead
        rem[..., k - 2, :] -= m0 * lead
        rem[..., k, :] = 0.0
    return rem[..., :2, :]


def reparametrize(c: np.ndarray, a: float | np.ndarray, b: float | np.ndarray) -> np.ndarray:
    """``C(a t + b)`` (same motion, new parameter); ``a != 0``, scalars or arrays broadcasting
    against ``c``'s batch shape ``(...)``."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if (a == 0).any():
        raise ValueError("reparametrization needs a != 0")
    n = c.shape[-2] - 1
    j = np.arange(n + 1)
    # (a t + b)^k expanded by the binomial theorem: coefficient j of C(a t + b) is
    # sum_k comb(k, j) a^j b^(k - j) c_k, one matrix product per item.
    binom = _binomials(n)
    shift = a[..., None, None] ** j[:, None] * b[..., None, None] ** np.maximum(j - j[:, None], 0)
    return (binom * shift) @ c


@functools.cache
def _binomials(n: int) -> np.ndarray:
    """``comb(k, j)`` ``(n+1, n+1)`` at ``[j, k]`` (zero for ``j > k``); cached, read only."""
    out = np.array([[math.comb(k, j) for k in range(n + 1)] for j in range(n + 1)], dtype=float)
    out.flags.writeable = False
    return out


def real_poly_roots(coeffs: np.ndarray, rtol: float | None = None) -> np.ndarray:
    """Complex roots ``(..., d)`` of real polynomials ``(..., d+1)`` (ascending) by batched
    companion-matrix eigenvalues.

    Without ``rtol`` the leading coefficient must be nonzero. With ``rtol``, leading coefficients
    ``|c| <= rtol * max|c|`` count as zero (degree drop = roots at t = inf): an item of effective
    degree e gets its e roots first and NaN for the other d - e (all NaN if constant or zero).
    """
    coeffs = np.asarray(coeffs, dtype=np.float64)
    d = coeffs.shape[-1] - 1
    if rtol is None:
        return _companion_roots(coeffs)
    big = np.abs(coeffs) > rtol * np.abs(coeffs).max(axis=-1, keepdims=True)
    deg = np.where(big.any(-1), d - np.argmax(big[..., ::-1], axis=-1), 0)
    out = np.full(coeffs.shape[:-1] + (d,), np.nan, dtype=np.complex128)
    for e in np.unique(deg[deg > 0]):  # at most d groups, each batched
        sel = deg == e
        out[sel, :e] = _companion_roots(coeffs[sel][:, : e + 1])
    return out


def _companion_roots(coeffs: np.ndarray) -> np.ndarray:
    d = coeffs.shape[-1] - 1
    comp = np.zeros(coeffs.shape[:-1] + (d, d))
    comp[..., 1:, :-1] = np.eye(d - 1)
    comp[..., :, -1] = -coeffs[..., :-1] / coeffs[..., -1:]
    return np.linalg.eigvals(comp)
