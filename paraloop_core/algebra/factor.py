"""Factorization of generic monic motion polynomials (HSS13a) and Bennett flips (paper App. B).

Batched kernels (``*_batch``) return results with a validity mask and a reason code per item
(degenerate items as masks); the public single-item functions raise
:class:`~paraloop_core.errors.NonGenericMotionError` with a clear message.
Linear factors ``h`` are ``(..., 8)`` dual quaternions; ``t - h`` is a rotation about the axis
with direction ``h[1:4]`` and moment ``h[5:8]`` (MATH section 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from paraloop_core.algebra import dq, poly
from paraloop_core.errors import NonGenericMotionError
from paraloop_core.tolerance import TOL

#: Reason codes of the batched kernels (index = code).
REASONS = ("ok", "real-root", "repeated-factor", "singular-remainder", "translational-factor")
_MESSAGES = {
    "real-root": "the norm polynomial has a real root: the motion passes through a singular "
    "pose or contains a translational factor, so it has no factorization into rotations",
    "repeated-factor": "the norm polynomial has a repeated quadratic factor: the motion has "
    "fewer than n! distinct factorizations",
    "singular-remainder": "the remainder of the HSS algorithm has a non-invertible leading "
    "coefficient: the primal part has a real polynomial factor (not generic)",
    "translational-factor": "a linear factor is a pure translation, not a rotation",
}


def norm_quadratics_batch(c_monic: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quadratic factors of the norm polynomial of monic ``C`` ``(..., n+1, 8)``.

    Returns ``(m, code)``: ``m`` ``(..., n, 2)`` holding ``[m0, m1]`` of ``t^2 + m1 t + m0``,
    sorted by ``m0`` then ``m1`` (a canonical labelling A, B, C, ...), and a reason code ``(...)``.
    """
    n = c_monic.shape[-2] - 1
    roots = poly.real_poly_roots(poly.norm_poly(c_monic))
    # Keep the n roots in the upper half plane (conjugate pairs of a real polynomial).
    order = np.argsort(-roots.imag, axis=-1)[..., :n]
    z = np.take_along_axis(roots, order, axis=-1)
    code = np.zeros(z.shape[:-1], dtype=np.int8)
    real = np.any(np.abs(z.imag) <= TOL.root_imag * (1.0 + np.abs(z)), axis=-1)
    m = np.stack([np.abs(z) ** 2, -2.0 * z.real], axis=-1)
    m = np.take_along_axis(m, np.lexsort((m[..., 1], m[..., 0]), axis=-1)[..., None], axis=-2)
    scale = 1.0 + np.abs(m).max(axis=(-2, -1))
    gaps = np.abs(np.diff(m, axis=-2)).max(axis=-1).min(axis=-1) if n > 1 else np.inf
    code = np.where(gaps <= TOL.repeated * scale, 2, code)
    code = np.where(real, 1, code)
    return m, code


def factorize_batch(c_monic: np.ndarray, quads: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """HSS13a: ``C = (t - h_0)...(t - h_{n-1})`` with ``norm(t - h_i) = quads[..., i, :]``.

    ``c_monic`` ``(..., n+1, 8)``, ``quads`` ``(..., n, 2)`` (``[m0, m1]``, in the wanted
    left-to-right order). Returns ``(h (..., n, 8), code (...))``.
    """
    n = c_monic.shape[-2] - 1
    cur = c_monic
    hs = [None] * n
    code = np.zeros(c_monic.shape[:-2], dtype=np.int8)
    for i in range(n - 1, -1, -1):
        rem = poly.mod_quadratic(cur, quads[..., i, :])
        r0, r1 = rem[..., 0, :], rem[..., 1, :]
        p1 = np.linalg.norm(r1[..., :4], axis=-1)
        bad = p1 <= TOL.singular * (1e-300 + np.abs(rem).max(axis=(-2, -1)))
        code = np.where(bad & (code == 0), 3, code)
        r1 = np.where(bad[..., None], dq.IDENTITY, r1)
        h = -dq.mul(dq.inv(r1), r0)
        h = clean_factor(h)
        hs[i] = h
        cur, _ = poly.right_divide_linear(cur, h)
    h = np.stack(hs, axis=-2)
    pnorm = np.linalg.norm(h[..., 1:4], axis=-1)
    trans = np.any(pnorm <= TOL.translation * (1.0 + np.abs(h).max(axis=-1)), axis=-1)
    code = np.where(trans & (code == 0), 4, code)
    return h, code


def clean_factor(h: np.ndarray) -> np.ndarray:
    """Remove round-off from a rotation factor: dual scalar 0, moment orthogonal to direction."""
    h = h.copy()
    h[..., 4] = 0.0
    p = h[..., 1:4]
    pp = np.maximum(np.sum(p * p, -1, keepdims=True), 1e-300)
    h[..., 5:8] -= np.sum(p * h[..., 5:8], -1, keepdims=True) / pp * p
    return h


def bennett_flip_batch(h1: np.ndarray, h2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bennett flip: ``(t-h1)(t-h2) = (t-k1)(t-k2)``, ``norm(t-k2) = norm(t-h1)``.

    Returns ``(k1, k2, ok)``; ``ok`` is False where ``X = h1~ - h2`` is not invertible.
    """
    x = dq.conj(h1) - h2
    px = np.linalg.norm(x[..., :4], axis=-1)
    ok = px > TOL.singular * (1.0 + np.abs(h1).max(-1) + np.abs(h2).max(-1))
    x = np.where(ok[..., None], x, dq.IDENTITY)
    k2 = clean_factor(dq.mul(dq.mul(dq.inv(x), h1), x))
    k1 = clean_factor(h1 + h2 - k2)
    return k1, k2, ok


def bennett_flip(h1: np.ndarray, h2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Single Bennett flip of two rotation factors ``(8,)``; raises if not defined."""
    k1, k2, ok = bennett_flip_batch(np.asarray(h1, float), np.asarray(h2, float))
    if not np.all(ok):
        raise NonGenericMotionError(
            "Bennett flip undefined: h1~ - h2 is not invertible (the two factors share their "
            "norm and axis data)",
            "singular-remainder",
        )
    return k1, k2


#: The six norm orders of a cubic as label indices (0=A, 1=B, 2=C), in hexagon order of Fig. 5:
#: ABC -(01)- BAC -(12)- BCA -(01)- CBA -(12)- CAB -(01)- ACB -(12)- ABC.
NORM_ORDERS = np.array([[0, 1, 2], [1, 0, 2], [1, 2, 0], [2, 1, 0], [2, 0, 1], [0, 2, 1]])
#: How each of the six is reached from ABC: (source index, flip position); walks both ways
#: round the hexagon so no chain is longer than three flips.
_FLIP_PLAN = ((0, 0, 1), (1, 1, 2), (2, 0, 3), (0, 1, 5), (5, 0, 4))


@dataclass(frozen=True)
class Factorizations:
    """All six factorizations of monic cubics.

    ``factors`` ``(..., 6, 3, 8)``: ``C = (t - f[j,0])(t - f[j,1])(t - f[j,2])``;
    ``norm_order`` ``(6, 3)``: label indices of each factor's norm quadratic (:data:`NORM_ORDERS`);
    ``quadratics`` ``(..., 3, 2)`` the labelled norm factors ``[m0, m1]`` (A, B, C);
    ``code`` ``(...)`` reason codes (0 = ok, see :data:`REASONS`).
    """

    factors: np.ndarray
    quadratics: np.ndarray
    code: np.ndarray

    @property
    def norm_order(self) -> np.ndarray:
        return NORM_ORDERS

    @property
    def ok(self) -> np.ndarray:
        return self.code == 0


def all_factorizations_batch(c_monic: np.ndarray) -> Factorizations:
    """Six factorizations of monic cubics ``(..., 4, 8)``: one by HSS13a (order ABC), five by
    Bennett flips. Invalid items carry a nonzero ``code``; their factors are meaningless."""
    c_monic = np.asarray(c_monic, dtype=np.float64)
    if c_monic.shape[-2:] != (4, 8):
        raise ValueError(f"a cubic motion polynomial must be (..., 4, 8), got {c_monic.shape}")
    quads, code = norm_quadratics_batch(c_monic)
    h, hcode = factorize_batch(c_monic, quads)
    code = np.where(code == 0, hcode, code)
    out = [None] * 6
    out[0] = h
    for src, pos, dst in _FLIP_PLAN:
        f = out[src].copy()
        k1, k2, ok = bennett_flip_batch(f[..., pos, :], f[..., pos + 1, :])
        f[..., pos, :], f[..., pos + 1, :] = k1, k2
        out[dst] = f
        code = np.where(~ok & (code == 0), 3, code)
    return Factorizations(np.stack(out, axis=-3), quads, code)


def check_motion(c: np.ndarray) -> np.ndarray:
    """Validate a single motion polynomial ``(n+1, 8)`` and return its monic form."""
    c = poly.as_poly(c, "motion polynomial")
    if c.ndim != 2:
        raise ValueError(f"expected one motion polynomial (n+1, 8), got {c.shape}")
    if not poly.is_motion_polynomial(c, TOL.residual):
        raise NonGenericMotionError(
            "not a motion polynomial: C C~ has a nonzero dual part (Study condition violated)",
            "not-motion",
        )
    try:
        mono, _ = poly.make_monic(c)
    except ValueError as exc:
        raise NonGenericMotionError(str(exc), "singular-leading") from exc
    return mono


def raise_for_code(code: int) -> None:
    """Raise :class:`NonGenericMotionError` for a nonzero reason code."""
    if code:
        reason = REASONS[int(code)]
        raise NonGenericMotionError(f"non-generic motion: {_MESSAGES[reason]}", reason)


def factorize(c: np.ndarray, order: list[int] | None = None) -> np.ndarray:
    """HSS13a factorization ``(n, 8)`` of one motion polynomial of any degree ``n >= 1``.

    ``order`` lists the canonical norm-quadratic labels (sorted by ``m0``) left to right;
    default ascending. Non-monic input is made monic first (``C = lead * monic``).
    """
    mono = check_motion(c)
    n = mono.shape[0] - 1
    quads, code = norm_quadratics_batch(mono)
    raise_for_code(int(code))
    order = list(range(n)) if order is None else list(order)
    if sorted(order) != list(range(n)):
        raise ValueError(f"order must be a permutation of 0..{n - 1}, got {order}")
    h, hcode = factorize_batch(mono, quads[order])
    raise_for_code(int(hcode))
    return h


def all_factorizations(c: np.ndarray) -> Factorizations:
    """All six factorizations of one cubic ``(4, 8)`` (made monic); raises if not generic."""
    mono = check_motion(c)
    if mono.shape != (4, 8):
        raise ValueError(f"expected a cubic (4, 8), got {mono.shape}")
    f = all_factorizations_batch(mono)
    raise_for_code(int(f.code))
    return f
