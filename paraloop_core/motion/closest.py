"""Closest pose on a motion to target poses under the metric of eq. 8 (MATH section 8 (2a)).

For a target ``S`` and motion ``C(t)`` of degree n put ``G(t) = S~ C(t)``; then
``dist^2(S, C(t)) = Q(t) / N(t)`` with ``Q = G^T M G`` (``M`` the quadratic form of
:func:`quadratic_form`) and ``N = |G_P|^2``, both of degree 2n. Critical points are the real
roots of ``Q'N - QN'``, whose ``t^(4n-1)`` coefficient cancels identically (degree <= 10 for
cubics); ``t = inf`` is tested too. All targets are solved in one batched companion-matrix call.
"""

from __future__ import annotations

import numpy as np

from paraloop_core.algebra import dq, factor, poly
from paraloop_core.motion import metric


def quadratic_form(inertia: metric.Inertia) -> np.ndarray:
    """Symmetric ``(8, 8)`` ``M`` with ``dist^2(1, G) = G^T M G / |G_P|^2`` (any scale of G).

    ``G^T M G = 4 |A G|^2`` where A stacks the linear terms of the closed form of eq. 8:
    ``g0'``, ``g' + g x c`` and ``sqrt(1/3) w a_k (g x e_k)``.
    """

    def cross_matrix(v: np.ndarray) -> np.ndarray:  # [v]_x with  g x v = -[v]_x g
        return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])

    rows = np.zeros((13, 8))
    rows[0, 4] = 1.0
    rows[1:4, 5:8] = np.eye(3)
    rows[1:4, 1:4] = -cross_matrix(inertia.center)
    scale = inertia.weight * inertia.semi_axes / np.sqrt(3.0)
    for k in range(3):  # three ellipsoid axes, not data
        rows[4 + 3 * k : 7 + 3 * k, 1:4] = -scale[k] * cross_matrix(inertia.axes[k])
    return 4.0 * rows.T @ rows


def _poly_quadform(a: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Coefficients ``(..., 2n+1)`` of ``A(t)^T m A(t)`` for ``A`` ``(..., n+1, 8)``."""
    n = a.shape[-2] - 1
    gram = np.einsum("...ik,kl,...jl->...ij", a, m, a)
    out = np.zeros(a.shape[:-2] + (2 * n + 1,))
    for i in range(n + 1):  # loop over the degree only
        out[..., i : i + n + 1] += gram[..., i, :]
    return out


def critical_polynomial(c: np.ndarray, s: np.ndarray, inertia: metric.Inertia) -> np.ndarray:
    """Numerator of ``d/dt dist^2(S, C(t))`` ``(..., 4n-1)`` ascending (degree <= 4n - 2).

    ``c`` ``(..., n+1, 8)`` motion, ``s`` ``(..., 8)`` targets (any scale), broadcasting.
    """
    g = dq.mul(dq.conj(s)[..., None, :], c)
    q = _poly_quadform(g, quadratic_form(inertia))
    nn = _poly_quadform(g, np.diag([1.0, 1, 1, 1, 0, 0, 0, 0]))
    k = np.arange(q.shape[-1])
    dq_, dn = (q * k)[..., 1:], (nn * k)[..., 1:]
    deg = q.shape[-1] - 1  # 2n
    num = np.zeros(q.shape[:-1] + (2 * deg,))
    for i in range(deg + 1):  # convolution over the (tiny) degree
        num[..., i : i + deg] += dq_ * nn[..., i : i + 1] - q[..., i : i + 1] * dn
    return num[..., :-1]  # the t^(4n-1) coefficient cancels identically


def _all_roots(coeffs: np.ndarray) -> np.ndarray:
    """Real parts of all complex roots ``(..., d)`` of polynomials ``(..., d+1)``.

    An exactly vanishing leading coefficient (degree drop: roots at t = inf, tested
    separately) is replaced by a value 1e-30 of the largest coefficient, which moves no finite
    root; a larger floor (1e-13) was seen to drag a real critical point from -708 to -117.
    """
    scale = np.max(np.abs(coeffs), axis=-1, keepdims=True)
    c = coeffs / np.where(scale > 0, scale, 1.0)
    lead = c[..., -1:]
    tiny = 1e-30
    c[..., -1:] = np.where(np.abs(lead) < tiny, np.where(lead < 0, -tiny, tiny), lead)
    c[..., :-1] = np.where(scale > 0, c[..., :-1], 0.0)  # all-zero: f constant, roots at 0
    return poly.real_poly_roots(c).real


def _horner(coeffs: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Values ``(..., k)`` of polynomials ``(..., d+1)`` (ascending) at points ``(..., k)``."""
    out = np.zeros_like(t) + coeffs[..., -1:]
    for k in range(coeffs.shape[-1] - 2, -1, -1):  # loop over the degree only
        out = out * t + coeffs[..., k : k + 1]
    return out


def closest_pose(
    c: np.ndarray, s: np.ndarray, inertia: metric.Inertia, robust: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Global closest pose on the closed motion cycle for each target.

    ``c`` ``(..., n+1, 8)`` motion polynomial, ``s`` ``(..., 8)`` target poses (any scale),
    batch shapes broadcast. Returns ``(t, d2)`` ``(...)``: the parameter (``inf`` allowed) and
    the squared metric distance there. Candidates: the real part of every root of the critical
    polynomial (so near-real roots are never lost to a threshold), two Newton steps on each,
    and ``t = inf``. The monomial-basis polynomial is ill-conditioned when roots cluster or lie
    far out (errors of 1e-3 in t, roots lost at ``|t| ~ 1e4``): ``robust`` adds 96 samples
    adapted to the motion (a candidate in every basin) and polishes the three best on the
    distance itself; it costs about 4x and is what reported distances use. Without it (the
    evolution's inner iterations) a clustered minimum can be off by ~1e-6 relative.
    """
    c = poly.as_poly(c, "motion")
    s = np.asarray(s, dtype=np.float64)
    if s.shape[-1:] != (8,) or not np.all(np.isfinite(s)):
        raise ValueError(f"targets must be finite (..., 8) poses, got shape {s.shape}")
    num = critical_polynomial(c, s, inertia)
    seeds = _all_roots(num)
    if robust:
        quads, _ = factor.norm_quadratics_batch(c)
        h0 = -0.5 * quads[..., 1]
        samples = poly.cycle_parameters(h0, np.sqrt(np.maximum(quads[..., 0] - h0**2, 0.0)), 32)
        seeds = np.concatenate(
            [seeds, np.broadcast_to(samples, seeds.shape[:-1] + samples.shape[-1:])], axis=-1)
    dnum = num[..., 1:] * np.arange(1, num.shape[-1])
    polished = seeds
    for _ in range(2):
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # flat spots
            step = _horner(num, polished) / _horner(dnum, polished)
        polished = np.where(np.isfinite(step), polished - step, polished)
    cand = np.concatenate([seeds, polished, np.full(seeds.shape[:-1] + (1,), np.inf)], axis=-1)
    d2 = metric.distance_sq(s[..., None, :], poly.evaluate_pose(c[..., None, :, :], cand), inertia)
    if robust:
        return _polish(c, s, inertia, cand, d2)
    best = np.argmin(d2, axis=-1)[..., None]
    return np.take_along_axis(cand, best, -1)[..., 0], np.take_along_axis(d2, best, -1)[..., 0]


def _polish(c: np.ndarray, s: np.ndarray, inertia: metric.Inertia, cand: np.ndarray,
            d2: np.ndarray, keep: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Refine the ``keep`` best candidates on the distance itself: parabola steps in
    ``u = t_to_param(t)`` of shrinking width (1e-3 .. 1e-7), each kept only if it lowers the
    value (robust where the polynomial's roots are inaccurate, e.g. clustered critical points).
    """
    k = np.argsort(d2, axis=-1)[..., :keep]
    u = poly.t_to_param(np.take_along_axis(cand, k, -1))
    best = np.take_along_axis(d2, k, -1)
    cc, ss = c[..., None, None, :, :], s[..., None, None, :]

    def dist(uu: np.ndarray) -> np.ndarray:
        return metric.distance_sq(ss, poly.evaluate_pose(cc, poly.param_to_t(uu)), inertia)

    for h in (1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 1e-6, 1e-7):
        fl, fr = np.moveaxis(dist(np.stack([u - h, u + h], axis=-1)), -1, 0)
        curv = fl - 2.0 * best + fr
        step = np.where(curv > 0, 0.5 * h * (fl - fr) / np.where(curv > 0, curv, 1.0), 0.0)
        un = u + np.clip(step, -h, h)
        fn = dist(un[..., None])[..., 0]
        better = fn < best
        u, best = np.where(better, un, u), np.where(better, fn, best)
    i = np.argmin(best, axis=-1)[..., None]
    return (poly.param_to_t(np.take_along_axis(u, i, -1))[..., 0],
            np.take_along_axis(best, i, -1)[..., 0])


def arc_table(
    c: np.ndarray, inertia: metric.Inertia, samples: int = 1024
) -> tuple[np.ndarray, np.ndarray]:
    """Cumulative metric arc length along the closed cycle of one motion ``(n+1, 8)``.

    Returns ``(u (K+1,), s (K+1,))`` over equally spaced ``u`` (``t = poly.param_to_t(u)``),
    starting at ``C(inf)`` (u = 0) with ``s[0] = 0``; ``s[-1]`` is the cycle length (chord sum).
    """
    u = np.linspace(0.0, 1.0, samples + 1)
    poses = poly.evaluate_pose(c, poly.param_to_t(u))
    seg = np.sqrt(np.maximum(metric.distance_sq(poses[:-1], poses[1:], inertia), 0.0))
    return u, np.concatenate([[0.0], np.cumsum(seg)])


def proportional_params(
    c: np.ndarray, targets: np.ndarray, inertia: metric.Inertia, t_first: float,
    samples: int = 1024,
) -> np.ndarray:
    """Guiding parameters ``(m-1,)`` by proportional spacing (MATH section 8 (2b), eq. 10).

    ``targets`` ``(m, 8)`` ordered, ``targets[0]`` the pose at ``C(inf)``. The closed cycle is
    split from ``C(inf)`` into arcs proportional to the target chords (closing chord included);
    it is walked forward when ``t_first`` (closest parameter of ``targets[1]``) lies on the
    shorter way forward, else backward.
    """
    u, s = arc_table(c, inertia, samples)
    length = s[-1]
    chords = np.sqrt(metric.distance_sq(targets, np.roll(targets, -1, axis=0), inertia))
    sigma = length * np.cumsum(chords)[:-1] / np.sum(chords)
    s1 = np.interp(poly.t_to_param(t_first), u, s)
    pos = sigma if s1 <= length - s1 else length - sigma
    return poly.param_to_t(np.interp(pos, s, u))
