"""Factorization of generic monic motion polynomials (HSS13a) and Bennett flips (paper App. B).

Batched kernels (``*_batch``) return results with a validity mask and a reason code per item
(degenerate items as masks); the public single-item functions raise
:class:`~paraloop_core.errors.NonGenericMotionError` with a clear message.
Linear factors ``h`` are ``(..., 8)`` dual quaternions; ``t - h`` is a rotation about the axis
with direction ``h[1:4]`` and moment ``h[5:8]`` (MATH section 1).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from paraloop_core.algebra import dq, exact, newton, poly
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


def conditioning_batch(c_monic: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Affine parameter map and length unit that make monic ``C`` ``(..., n+1, 8)`` O(1).

    Returns ``(a, b, length)`` ``(...)`` each: with ``t = a s + b`` the norm roots of
    ``C(a s + b) / a^n`` gather round ``s = i`` (``b + i a`` is an approximate minimax centre of
    the roots in the hyperbolic metric of the upper half plane, which affine maps preserve: the
    roots' remaining spread is intrinsic to the motion), and dividing its dual part by
    ``length`` makes dual and primal coefficients the same size. Factorization commutes with
    both maps (``t - h = a (s - (h - b)/a)``; scaling the dual part is an algebra automorphism),
    so conditioned results map back exactly; the tests of genericity done in the conditioned
    frame are invariant under affine reparametrization and a change of length unit.
    """
    return _conditioning(c_monic)[1:]


def _conditioning(c_monic: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(C(a s + b) / a^n, a, b, length)`` of :func:`conditioning_batch`."""
    n = c_monic.shape[-2] - 1
    b, a = hyperbolic_center(_upper_roots(poly.norm_poly(c_monic), n))
    cs = _affine(c_monic, a, b)
    primal = np.abs(cs[..., :4]).max(axis=(-2, -1))
    dual = np.abs(cs[..., 4:]).max(axis=(-2, -1))
    length = np.where(dual > 0, dual / np.maximum(primal, 1e-300), 1.0)
    return cs, a, b, length


_PM1 = np.array([1.0, -1.0])  # r^2 + 1 and r^2 - 1 in hyperbolic_center


@functools.cache
def _pairs(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Index arrays ``(i, j)`` of the pairs ``i < j`` of ``n`` items (cached)."""
    return np.triu_indices(n, 1)


def hyperbolic_center(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(x, y)`` ``(...)``: a point ``x + i y`` of the upper half plane whose largest hyperbolic
    distance to the points ``z`` ``(..., n)`` is (nearly) smallest, chosen among the points, the
    geodesic midpoints of two of them and their centroid on the hyperboloid model (where the
    normalized sum of two points is their midpoint). Degenerate input gives ``(0, 1)``."""
    z = np.where(np.isfinite(z) & (z.imag > 0), z, 1j)
    x, y = z.real, z.imag
    r2 = x * x + y * y
    y2 = (2 * y)[..., None]
    hyp = np.concatenate([(r2[..., None] + _PM1) / y2, (x / y)[..., None]], -1)  # (..., n, 3)
    i, j = _pairs(z.shape[-1])
    sums = np.concatenate([hyp, hyp[..., i, :] + hyp[..., j, :], hyp.sum(-2, keepdims=True)],
                          axis=-2)
    lorentz = sums[..., 0] ** 2 - sums[..., 1] ** 2 - sums[..., 2] ** 2
    cand = sums / np.sqrt(np.maximum(lorentz, 1e-300))[..., None]
    # cosh of the distance is the Minkowski product <X, Y> = X0 Y0 - X1 Y1 - X2 Y2
    cosh = np.einsum("...ka,...ma,a->...km", cand, hyp, np.array([1.0, -1.0, -1.0]))
    best = np.argmin(cosh.max(axis=-1), axis=-1)[..., None, None]
    c = np.take_along_axis(cand, best, axis=-2)[..., 0, :]
    yc = 1.0 / (c[..., 0] - c[..., 1])
    return c[..., 2] * yc, yc


def _upper_roots(norm: np.ndarray, n: int) -> np.ndarray:
    """The ``n`` roots ``(..., n)`` of real ``norm`` ``(..., 2n+1)`` with the largest imaginary
    parts (one of each conjugate pair)."""
    roots = poly.real_poly_roots(norm)
    order = np.argsort(-roots.imag, axis=-1)[..., :n]
    return np.take_along_axis(roots, order, axis=-1)


def _affine(c: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``C(a s + b) / a^n`` for batched ``a``, ``b`` ``(...)`` (monic stays monic)."""
    n = c.shape[-2] - 1
    return poly.reparametrize(c, a, b) / (np.asarray(a)[..., None, None] ** n)


def norm_quadratics_batch(c_monic: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quadratic factors of the norm polynomial of monic ``C`` ``(..., n+1, 8)``.

    Returns ``(m, code)``: ``m`` ``(..., n, 2)`` holding ``[m0, m1]`` of ``t^2 + m1 t + m0``,
    sorted by ``m0`` then ``m1`` (a canonical labelling A, B, C, ...), and a reason code ``(...)``.
    The code is float64's *suspicion* (see :func:`_conditioned_roots`);
    :func:`all_factorizations` confirms it in high precision before refusing.
    """
    cs, a, b, _ = _conditioned(c_monic)
    quads, _, code = _labelled_quadratics(cs, a, b)
    return quads, code


def _label_order(m: np.ndarray) -> np.ndarray:
    return np.lexsort((m[..., 1], m[..., 0]), axis=-1)


def _conditioned_roots(cs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Upper norm roots ``(..., n)`` of a conditioned monic ``cs`` and the suspected code.

    Genericity depends only on the hyperbolic distances ``d`` of the roots in the upper half
    plane (invariant under every real Moebius reparametrization and the length unit): a real
    root is at infinite distance from the others (``cosh d - 1 = |z_i - z_j|^2 / (2 y_i y_j)``
    above ``TOL.real_separation``), a repeated quadratic at distance 0 (``sinh(d/2)`` below
    ``TOL.repeated``).
    """
    n = cs.shape[-2] - 1
    z = _upper_roots(poly.norm_poly(cs), n)
    y = z.imag
    real = (y <= 0.0).any(axis=-1)
    code = np.zeros(z.shape[:-1], dtype=np.int8)
    if n > 1:
        i, j = _pairs(n)
        yy = np.maximum(y[..., i] * y[..., j], 1e-300)
        with np.errstate(over="ignore"):  # inf: a root on the real line (a three-pose fuzz case)
            sep = np.abs(z[..., i] - z[..., j]) ** 2 / (2.0 * yy)
        code = np.where(np.sqrt(sep.min(axis=-1) / 2.0) <= TOL.repeated, 2, code)
        real |= sep.max(axis=-1) >= TOL.real_separation
    return z, np.where(real, 1, code)


def factorize_batch(c_monic: np.ndarray, quads: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """HSS13a: ``C = (t - h_0)...(t - h_{n-1})`` with ``norm(t - h_i) = quads[..., i, :]``.

    ``c_monic`` ``(..., n+1, 8)``, ``quads`` ``(..., n, 2)`` (``[m0, m1]``, in the wanted
    left-to-right order). Returns ``(h (..., n, 8), code (...))``.
    """
    n = c_monic.shape[-2] - 1
    cur = c_monic
    h = np.empty(c_monic.shape[:-2] + (n, 8))
    code = np.zeros(c_monic.shape[:-2], dtype=np.int8)
    for i in range(n - 1, -1, -1):
        rem = poly.mod_quadratic(cur, quads[..., i, :])
        r0, r1 = rem[..., 0, :], rem[..., 1, :]
        p1 = np.sqrt((r1[..., :4] ** 2).sum(axis=-1))
        bad = p1 <= TOL.singular * (1e-300 + np.abs(rem).max(axis=(-2, -1)))
        code = np.where(bad & (code == 0), 3, code)
        r1 = np.where(bad[..., None], dq.IDENTITY, r1)
        h[..., i, :] = clean_factor(-dq.mul(dq.inv(r1), r0))
        cur, _ = poly.right_divide_linear(cur, h[..., i, :])
    pnorm = np.sqrt((h[..., 1:4] ** 2).sum(axis=-1))
    trans = (pnorm <= TOL.translation * (1.0 + np.abs(h).max(axis=-1))).any(axis=-1)
    code = np.where(trans & (code == 0), 4, code)
    return h, code


def clean_factor(h: np.ndarray) -> np.ndarray:
    """Remove round-off from a rotation factor: dual scalar 0, moment orthogonal to direction."""
    h = h.copy()
    h[..., 4] = 0.0
    p = h[..., 1:4]
    pp = np.maximum((p * p).sum(-1, keepdims=True), 1e-300)
    h[..., 5:8] -= (p * h[..., 5:8]).sum(-1, keepdims=True) / pp * p
    return h


def bennett_flip_batch(h1: np.ndarray, h2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bennett flip: ``(t-h1)(t-h2) = (t-k1)(t-k2)``, ``norm(t-k2) = norm(t-h1)``.

    Returns ``(k1, k2, ok)``; ``ok`` is False where ``X = h1~ - h2`` is not invertible.
    """
    x = dq.conj(h1) - h2
    px = np.sqrt((x[..., :4] ** 2).sum(axis=-1))
    ok = px > TOL.singular * (1.0 + np.abs(h1).max(-1) + np.abs(h2).max(-1))
    x = np.where(ok[..., None], x, dq.IDENTITY)
    k2 = clean_factor(dq.mul(dq.mul(dq.inv(x), h1), x))
    k1 = clean_factor(h1 + h2 - k2)
    return k1, k2, ok


def bennett_flip(h1: np.ndarray, h2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Single Bennett flip of two rotation factors ``(8,)``; raises if not defined."""
    k1, k2, ok = bennett_flip_batch(np.asarray(h1, float), np.asarray(h2, float))
    if not ok.all():
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


def _flip_stages(plan: tuple[tuple[int, int, int], ...]) -> list[tuple[np.ndarray, ...]]:
    """The flips of ``plan`` grouped by chain length: ``(src, pos, dst)`` index arrays per
    stage, each stage's sources computed by the earlier stages."""
    depth = {0: 0}
    for src, _, dst in plan:  # the plan lists every source before its use
        depth[dst] = depth[src] + 1
    return [tuple(np.array([f[i] for f in plan if depth[f[2]] == d]) for i in range(3))
            for d in range(1, max(depth.values()) + 1)]


_FLIP_STAGES = _flip_stages(_FLIP_PLAN)


@dataclass(frozen=True)
class Factorizations:
    """All six factorizations of monic cubics, or both of a quadratic.

    ``factors`` ``(..., 6, 3, 8)``: ``C = (t - f[j,0])(t - f[j,1])(t - f[j,2])`` (a quadratic's
    ``(2, 2, 8)``, :func:`quadratic_factorizations`);
    ``norm_order`` ``(6, 3)``: label indices of each factor's norm quadratic (:data:`NORM_ORDERS`;
    a quadratic's ``(2, 2)`` :data:`QUADRATIC_ORDERS`);
    ``quadratics`` ``(..., 3, 2)`` the labelled norm factors ``[m0, m1]`` (A, B, C);
    ``code`` ``(...)`` reason codes (0 = ok, see :data:`REASONS`).
    """

    factors: np.ndarray
    quadratics: np.ndarray
    code: np.ndarray

    @property
    def norm_order(self) -> np.ndarray:
        return NORM_ORDERS if self.factors.shape[-2] == 3 else QUADRATIC_ORDERS

    @property
    def ok(self) -> np.ndarray:
        return self.code == 0


def all_factorizations_batch(c_monic: np.ndarray) -> Factorizations:
    """Six factorizations of monic cubics ``(..., 4, 8)``: one by HSS13a (order ABC), five by
    Bennett flips. Invalid items carry a nonzero ``code``; their factors are meaningless.

    Computed in the conditioned frame of :func:`conditioning_batch` (parameter and length unit
    normalized) and mapped back, so the result and its genericity verdict do not depend on the
    length unit or on an affine reparametrization of the input.
    """
    c_monic = np.asarray(c_monic, dtype=np.float64)
    if c_monic.shape[-2:] != (4, 8):
        raise ValueError(f"a cubic motion polynomial must be (..., 4, 8), got {c_monic.shape}")
    cs, h, quads, code, a, b, length = _hss_conditioned(c_monic)
    fs = np.empty(h.shape[:-2] + (6, 3, 8))
    fs[..., 0, :, :] = h
    for src, pos, dst in _FLIP_STAGES:  # the flips of a stage are independent: one batch
        f = fs[..., src, :, :]  # (..., k, 3, 8), a copy
        k = np.arange(len(src))
        k1, k2, ok = bennett_flip_batch(f[..., k, pos, :], f[..., k, pos + 1, :])
        f[..., k, pos, :], f[..., k, pos + 1, :] = k1, k2
        fs[..., dst, :, :] = f
        code = np.where(~ok.all(axis=-1) & (code == 0), 3, code)
    loose = (code == 0) & (product_residual(fs, cs[..., None, :, :]).max(axis=-1)
                           > TOL.factor_residual)
    if loose.any():
        fs[loose] = refine_cubic_factors(fs[loose], cs[loose][..., None, :, :])
    return Factorizations(_unconditioned(fs, a, b, length), quads, code)


def refine_cubic_factors(h: np.ndarray, c_monic: np.ndarray, steps: int = 2) -> np.ndarray:
    """Newton steps on ``C = (t - h0)(t - h1)(t - h2)`` for factors ``h`` ``(..., 3, 8)`` of
    monic cubics ``c_monic`` ``(..., 4, 8)`` (broadcasting).

    Motions near a singular pose have clustered norm roots; HSS then loses digits (residuals up
    to 1e-2 were seen on random designs) though the factorization itself is well defined. The
    factorization is an isolated solution (``h1 - h0`` invertible), so Newton on the 24
    coefficient equations in the 21 free coefficients (least squares) restores it.
    """
    h = np.array(h, dtype=np.float64)
    for _ in range(steps):
        h[..., newton.FREE] += newton.cubic_step(h, c_monic)
        h = clean_factor(h)
    return h


def hss_batch(c_monic: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One factorization (HSS13a, norm order A, B, C) ``(..., n, 8)`` of monic ``C``
    ``(..., n+1, 8)``, computed in the conditioned frame like :func:`all_factorizations_batch`,
    and a reason code ``(...)`` (float64's suspicion: nonzero items are meaningless)."""
    _, h, _, code, a, b, length = _hss_conditioned(np.asarray(c_monic, dtype=np.float64))
    return _unconditioned(h, a, b, length), code


def _hss_conditioned(c_monic: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(cs, h_s, quads, code, a, b, length)``: the conditioned cubic, its HSS factors, the
    labelled norm quadratics in t, the code, and the map back (:func:`_unconditioned`)."""
    cs, a, b, length = _conditioned(c_monic)
    quads, quads_s, code = _labelled_quadratics(cs, a, b)
    h, hcode = factorize_batch(cs, quads_s)
    return cs, h, quads, np.where(code == 0, hcode, code), a, b, length


def _conditioned(c_monic: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(cs, a, b, length)``: the conditioned cubic ``cs`` (parameter ``s``, ``t = a s + b``,
    lengths divided by ``length``) of :func:`conditioning_batch`."""
    cs, a, b, length = _conditioning(c_monic)
    return dq.scale_lengths(cs, 1.0 / length[..., None]), a, b, length


def _unconditioned(h: np.ndarray, a: np.ndarray, b: np.ndarray, length: np.ndarray
                   ) -> np.ndarray:
    """Factors ``(..., K, n, 8)`` or ``(..., n, 8)`` of the conditioned cubic mapped back:
    ``h = a h_s + b`` with the dual part in the caller's length unit."""
    extra = h.ndim - a.ndim - 1
    ex = (slice(None),) * a.ndim + (None,) * extra
    h = dq.scale_lengths(h, length[ex]) * a[ex + (None,)]
    h[..., 0] += b[ex]
    return h


def _labelled_quadratics(cs: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, ...]:
    """``(quads, quads_s, code)``: norm quadratics in the caller's parameter ``t`` (sorted,
    the labels A, B, C) and the same ones in the conditioned parameter ``s``; genericity code."""
    zs, code = _conditioned_roots(cs)
    z = a[..., None] * zs + b[..., None]
    both = np.concatenate([z, zs], axis=-1)[..., None]  # (..., 2n, 1): t, then s
    m = np.concatenate([np.abs(both) ** 2, -2.0 * both.real], axis=-1)
    m, ms = m[..., :zs.shape[-1], :], m[..., zs.shape[-1]:, :]
    order = _label_order(m)[..., None]
    return np.take_along_axis(m, order, -2), np.take_along_axis(ms, order, -2), code


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


def product_residual(h: np.ndarray, c_monic: np.ndarray) -> np.ndarray:
    """Relative residual ``(...)`` of factors ``h`` ``(..., n, 8)`` against monic ``C``
    ``(n+1, 8)``: the larger of the primal and dual parts' errors, each relative to that part's
    largest coefficient (so a change of length unit does not hide the primal error)."""
    err = np.abs(poly.from_factors(h) - c_monic)
    size = np.abs(c_monic).reshape(-1, 2, 4).max(axis=(0, 2))
    rel = err.reshape(*err.shape[:-1], 2, 4).max(axis=(-3, -1)) / np.maximum(size, 1e-300)
    return rel.max(axis=-1)


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
    order = list(range(n)) if order is None else list(order)
    if sorted(order) != list(range(n)):
        raise ValueError(f"order must be a permutation of 0..{n - 1}, got {order}")
    h, _, back = _factorize_conditioned(mono, order)
    return _unconditioned(h, *back)


def _factorize_conditioned(mono: np.ndarray, order: list[int]
                           ) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
    """``(h_s, quads, (a, b, length))``: the HSS factors of monic ``mono`` in the conditioned
    frame (norm order ``order``), its labelled norm quadratics in t and the map back
    (:func:`_unconditioned`); raises :class:`NonGenericMotionError` (float64's verdict)."""
    cs, a, b, length = _conditioned(mono)
    quads, quads_s, code = _labelled_quadratics(cs, a, b)
    raise_for_code(int(code))
    h, hcode = factorize_batch(cs, quads_s[order])
    raise_for_code(int(hcode))
    return h, quads, (a, b, length)


#: The two norm orders of a quadratic (AB, BA), one Bennett flip apart.
QUADRATIC_ORDERS = np.array([[0, 1], [1, 0]])


def quadratic_factorizations(c: np.ndarray) -> Factorizations:
    """Both factorizations ``(t - h_1)(t - h_2) = (t - k_1)(t - k_2)`` of one quadratic
    ``(3, 8)`` (made monic): HSS13a in norm order A, B and its Bennett flip (norm order B, A;
    :data:`QUADRATIC_ORDERS`), computed in the conditioned frame like the cubic's. Raises
    :class:`NonGenericMotionError` when float64 finds the motion not generic (no high-precision
    confirmation: a quadratic near that edge is refused) or the flip is undefined."""
    mono = check_motion(c)
    if mono.shape != (3, 8):
        raise ValueError(f"expected a quadratic (3, 8), got {mono.shape}")
    h, quads, back = _factorize_conditioned(mono, [0, 1])
    k1, k2 = bennett_flip(h[0], h[1])
    fs = _unconditioned(np.stack([h, np.stack([k1, k2])]), *back)
    residual = float(product_residual(fs, mono).max())
    if not residual <= TOL.factor_exact:
        raise NonGenericMotionError(
            f"non-generic motion: the factors of the quadratic multiply back to it only within "
            f"{residual:.1e} (float64 lost the factorization; move the poses apart)",
            "singular-remainder")
    return Factorizations(fs, quads, np.int8(0))


def all_factorizations(c: np.ndarray) -> Factorizations:
    """All six factorizations of one cubic ``(4, 8)`` (made monic); raises if not generic.

    A float64 suspicion of non-genericity is confirmed in high precision
    (:mod:`~paraloop_core.algebra.exact`) before refusing; if the motion is generic after all,
    the factorizations are computed there and rounded to float64. So are they when the refined
    float64 factors still do not multiply back to the motion (``TOL.factor_exact``).
    """
    mono = check_motion(c)
    if mono.shape != (4, 8):
        raise ValueError(f"expected a cubic (4, 8), got {mono.shape}")
    f = all_factorizations_batch(mono)
    if f.code == 0 and product_residual(f.factors, mono).max() <= TOL.factor_exact:
        return f
    # float64's roots seed a polishing that can only confirm genericity (a refusal is always
    # the companion matrix's): three distinct simple upper roots and their conjugates are all
    # six roots of the norm polynomial, so none is real and none repeated
    m0, m1 = f.quadratics[..., 0], f.quadratics[..., 1]
    with np.errstate(invalid="ignore"):
        hints = -m1 / 2 + 1j * np.sqrt(np.maximum(m0 - m1 ** 2 / 4, 0.0))
    hints = hints if np.all(np.isfinite(hints)) else None
    factors, quads, code = exact.factorizations(mono, _FLIP_PLAN, hints)
    raise_for_code(code)
    return Factorizations(factors, quads, np.int8(0))
