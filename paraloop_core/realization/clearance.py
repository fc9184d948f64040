"""Exact minimum distance between a fixed and a moving segment over the whole cycle (MATH §12).

Setting: segment A is fixed in link i's home frame, segment B is fixed in link j and moves by the
relative motion ``R(t)`` (a motion polynomial ``(k+1, 8)``, :func:`loops.relative_motion`), for t
in ``R u {inf}``. The squared distance of each of the nine Lumelsky cases is a rational function
``F/G`` with ``G > 0``; its critical points are the real roots of ``F'G - FG'`` (leading term
cancels identically). The exact minimum is the smallest true clamped segment distance over all
critical points and ``t = inf`` (extra candidates are harmless: each is a real distance).

Scalar polynomials are arrays ``(..., n)`` with ascending coefficients; vector polynomials are
``(..., 3, n)``. Everything is batched over a leading item axis.

Conditioning: the polynomials of :class:`MotionData` are in a parameter ``s`` with
``t = a s + b`` (:func:`charts`: the norm roots gather round ``s = i``). A motion whose norm
roots lie far apart in the hyperbolic metric (a fast and a slow turn) has critical polynomials
whose roots no single parameter resolves (a contact at t = 5842 was missed in t, another one
in the centred s): each far root gets a chart of its own (``extra``) whose critical points are
added to the candidates. Every ``t`` taken or returned here is the design's.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from functools import cache, cached_property

import numpy as np

from paraloop_core.algebra import dq, factor, poly
from paraloop_core.linkage import loops
from paraloop_core.tolerance import TOL

#: Samples of the cycle for cheap upper bounds (true distances; s = inf included), uniform in
#: ``u`` of the conditioned parameter: ``s = poly.param_to_t(u)``.
SAMPLE_U = np.linspace(0.0, 1.0, 48, endpoint=False)
SAMPLE_S = poly.param_to_t(SAMPLE_U)


@cache
def _convolution(m: int, n: int) -> np.ndarray:
    """0/1 matrix ``(m n, m+n-1)`` summing the anti-diagonals of an ``m x n`` outer product."""
    out = np.zeros((m * n, m + n - 1))
    out[np.arange(m * n), np.add.outer(np.arange(m), np.arange(n)).ravel()] = 1.0
    return out


def pmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Product of scalar polynomials ``(..., m) x (..., n) -> (..., m+n-1)`` (broadcasting)."""
    m, n = a.shape[-1], b.shape[-1]
    outer = a[..., :, None] * b[..., None, :]
    return outer.reshape(outer.shape[:-2] + (m * n,)) @ _convolution(m, n)


def pder(a: np.ndarray) -> np.ndarray:
    """Derivative ``(..., n) -> (..., n-1)``."""
    return a[..., 1:] * np.arange(1, a.shape[-1])


def vcross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of vector polynomials ``(..., 3, m) x (..., 3, n)`` (or constants ``n=1``)."""
    ax, ay, az = a[..., 0, :], a[..., 1, :], a[..., 2, :]
    bx, by, bz = b[..., 0, :], b[..., 1, :], b[..., 2, :]
    return np.stack(
        [pmul(ay, bz) - pmul(az, by), pmul(az, bx) - pmul(ax, bz), pmul(ax, by) - pmul(ay, bx)],
        axis=-2,
    )


def vsq(a: np.ndarray) -> np.ndarray:
    """``|a(t)|^2`` of a vector polynomial ``(..., 3, n) -> (..., 2n-1)``."""
    return np.sum(pmul(a, a), axis=-2)


def segment_distance(p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """Distance ``(...)`` between segments ``[p0, p1]`` and ``[q0, q1]`` (points ``(..., 3)``,
    broadcasting); exact for parallel and zero-length segments (clamped closest points).
    Computed per component (views ``(3, ...)``: long inner loops, no 3-wide reductions)."""
    p0, p1, q0, q1 = (np.moveaxis(x, -1, 0) for x in np.broadcast_arrays(
        *(np.asarray(x, dtype=np.float64) for x in (p0, p1, q0, q1))))
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, b = _dot3(d1, d1), _dot3(d2, d2), _dot3(d1, d2)
    c, f = _dot3(d1, r), _dot3(d2, r)
    tiny = TOL.zero * (a + e + _dot3(r, r)) + 1e-300
    a_ok, e_ok = a > tiny, e > tiny
    den = a * e - b * b
    # Interior solution on the lines; parallel (den ~ 0) starts from s = 0 and clamps below.
    s = np.where(den > TOL.zero * a * e, (b * f - c * e) / np.where(den > 0, den, 1.0), 0.0)
    s = np.where(a_ok, np.clip(s, 0.0, 1.0), 0.0)
    # Second segment a point: the closest point on the first is the clamped projection.
    s = np.where(a_ok & ~e_ok, np.clip(-c / np.where(a_ok, a, 1.0), 0.0, 1.0), s)
    u = np.where(e_ok, (b * s + f) / np.where(e_ok, e, 1.0), 0.0)
    # Clamp u and recompute s for the clamped u (Ericson, Real-Time Collision Detection 5.1.9).
    uc = np.clip(u, 0.0, 1.0)
    s = np.where(u != uc, np.clip((b * uc - c) / np.where(a_ok, a, 1.0), 0.0, 1.0), s)
    s = np.where(a_ok, s, 0.0)
    diff = r + s * d1 - uc * d2
    return np.sqrt(_dot3(diff, diff))


def _dot3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a . b`` of component-first vectors ``(3, ...)``."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product ``(...)`` of vectors ``(..., 3)``."""
    return np.einsum("...i,...i->...", a, b)


#: A parameter map ``t = a s + b`` as ``(a, b)``.
Chart = tuple[float, float]


@dataclass(frozen=True)
class MotionData:
    """Polynomial maps of relative motions ``R`` ``(M, k+1, 8)`` of one common degree k.

    ``norm`` ``(M, n)``: ``N = |R_P|^2`` (n = 2k+1); ``lines`` ``(M, 6, 6, n)``: Plücker
    ``(l, m)`` -> numerator of ``R (l + eps m) R~`` (scaled by N); ``points`` ``(M, 3, 4, n)``:
    ``[x, 1]`` -> numerator ``X(s)`` of ``R(s)(x) = X / N``; all in ``s`` with the design's
    ``t = a s + b`` (``a > 0``).
    """

    motions: np.ndarray
    norm: np.ndarray
    lines: np.ndarray
    points: np.ndarray
    a: float = 1.0
    b: float = 0.0
    extra: tuple[MotionData, ...] = ()

    def to_s(self, t: np.ndarray) -> np.ndarray:
        """Parameter ``s`` of design parameters ``t`` (infinities kept)."""
        return (np.asarray(t, dtype=np.float64) - self.b) / self.a

    def to_t(self, s: np.ndarray) -> np.ndarray:
        """Design parameters ``t`` of ``s`` (infinities kept)."""
        return self.a * np.asarray(s, dtype=np.float64) + self.b

    @property
    def degree(self) -> int:
        return self.motions.shape[-2] - 1


def motion_data(motions: np.ndarray, a: float = 1.0, b: float = 0.0,
                extra: tuple[Chart, ...] = ()) -> MotionData:
    """Build :class:`MotionData` from motion polynomials ``(M, k+1, 8)`` of one degree k >= 1
    in the design's t, worked in ``s`` with ``t = a s + b`` (``a > 0``); ``extra`` charts
    ``(a, b)`` add critical points (module docstring)."""
    if not (np.isfinite(a) and a > 0 and np.isfinite(b)):
        raise ValueError(f"the parameter map t = a s + b needs finite a > 0 and b, got {a}, {b}")
    more = tuple(motion_data(motions, ea, eb) for ea, eb in extra)
    r = poly.reparametrize(np.asarray(motions, dtype=np.float64), a, b)
    r = r / np.abs(r).max(axis=(-2, -1), keepdims=True)  # a real factor: the same motion
    rs = r[:, None]  # (M, 1, k+1, 8) against 6 or 4 basis elements
    eye = np.eye(8)
    basis_lines = eye[[1, 2, 3, 5, 6, 7]][:, None, :]  # (6, 1, 8) pure l or eps m
    moved = poly.mul(poly.mul(rs, basis_lines), poly.conj(rs))  # (M, 6, n, 8)
    lines = np.concatenate([moved[..., 1:4], moved[..., 5:8]], axis=-1)  # (M, 6in, n, 6out)
    basis_pts = np.stack([eye[0] + eye[5], eye[0] + eye[6], eye[0] + eye[7], eye[0]])[:, None]
    # Point action Q (1 + eps x) (P~ - eps D~): the dual vector part is the numerator X(t).
    acted = poly.mul(poly.mul(rs, basis_pts), dq.conj(dq.eps_conj(rs)))[..., 5:8]  # (M,4,n,3)
    acted[:, :3] -= acted[:, 3:4]  # affine: columns for x, then the constant column
    return MotionData(
        r,
        poly.norm_poly(r),
        np.transpose(lines, (0, 3, 1, 2)),
        np.transpose(acted, (0, 3, 1, 2)),
        float(a),
        float(b),
        more,
    )


#: ``cosh`` of the hyperbolic distance from the centre beyond which a norm root gets a chart.
FAR_ROOT = 10.0


def charts(joint_factors: np.ndarray) -> tuple[Chart, tuple[Chart, ...]]:
    """Parameter maps ``t = a s + b`` of a loop ``(6, 8)``: ``(a, b)`` centring its norm roots
    at ``s = i`` (minimax in the hyperbolic metric, :func:`factor.hyperbolic_center`) and one
    ``(Im z, Re z)`` per root ``z`` farther than :data:`FAR_ROOT`."""
    z = loops.norm_roots(joint_factors)
    b, a = (float(v) for v in factor.hyperbolic_center(z))
    cosh = 1.0 + np.abs(z - (b + 1j * a)) ** 2 / (2.0 * a * z.imag)
    return (a, b), tuple((float(r.imag), float(r.real)) for r in z[cosh > FAR_ROOT])


def chart_roots(md: MotionData, roots_in: Callable[[MotionData], np.ndarray]) -> np.ndarray:
    """``roots_in(md)`` ``(B, K)`` (parameters of ``md``) joined by those of its ``extra``
    charts mapped into ``md``'s s: ``(B, K (1 + len(extra)))``."""
    return np.concatenate([roots_in(md)] + [md.to_s(ex.to_t(roots_in(ex))) for ex in md.extra],
                          axis=1)


class PairMotions:
    """Relative motions ``R_ab`` (:func:`loops.relative_motion`) of the link pairs ``keys``,
    grouped by degree as :class:`MotionData` (``groups``; pairs in first-seen order of ``keys``),
    ``where[(a, b)] = (degree, index)``, and their rotations/translations at :data:`SAMPLE_S`
    (``rot``, ``trans``). All in the loop's conditioned parameter (module docstring)."""

    def __init__(self, jf: np.ndarray, keys: Iterable[tuple[int, int]]):
        (a, b), extra = charts(jf)
        polys = {k: loops.relative_motion(jf, *k) for k in keys if k[0] != k[1]}
        self.where: dict[tuple[int, int], tuple[int, int]] = {}
        self.groups: dict[int, MotionData] = {}
        for deg in sorted({m.shape[0] - 1 for m in polys.values()}):
            members = [k for k, m in polys.items() if m.shape[0] - 1 == deg]
            self.groups[deg] = motion_data(np.stack([polys[k] for k in members]), a, b, extra)
            self.where.update({k: (deg, n) for n, k in enumerate(members)})

    # Sampled rigid maps for cheap upper bounds (true distances at 48 times); computed on first
    # use only: the thin collision check never needs them.
    @cached_property
    def _sampled(self) -> dict[int, np.ndarray]:
        return {deg: poly.evaluate_pose(md.motions[:, None], SAMPLE_S)
                for deg, md in self.groups.items()}

    @cached_property
    def rot(self) -> dict[int, np.ndarray]:
        """Rotation matrices ``(M, T, 3, 3)`` per degree at :data:`SAMPLE_S`."""
        return {deg: dq.rotation_matrix(q) for deg, q in self._sampled.items()}

    @cached_property
    def trans(self) -> dict[int, np.ndarray]:
        """Translations ``(M, T, 3)`` per degree at :data:`SAMPLE_S`."""
        return {deg: dq.translation_of(q) for deg, q in self._sampled.items()}

    def data(self, keys: Iterable[tuple[int, int]]) -> list[tuple[MotionData, int]]:
        """``(data, index)`` of the motion of each link pair of ``keys``."""
        return [(self.groups[deg], n) for deg, n in (self.where[k] for k in keys)]

    def split(self, keys: list[tuple[int, int]]):
        """``(degree, positions, motion indices)`` for items with link-pair ``keys``."""
        where = np.array([self.where[k] for k in keys]).reshape(-1, 2)
        for deg in self.groups:
            pos = np.flatnonzero(where[:, 0] == deg)
            if pos.size:
                yield deg, pos, where[pos, 1]


def plucker(seg: np.ndarray) -> np.ndarray:
    """Unnormalized Plücker ``(l, m)`` ``(..., 6)`` of segments ``(..., 2, 3)``."""
    x, y = seg[..., 0, :], seg[..., 1, :]
    d = y - x
    # m = x cross y written out: np.cross costs more than the arithmetic at these sizes
    m = np.stack([x[..., 1] * y[..., 2] - x[..., 2] * y[..., 1],
                  x[..., 2] * y[..., 0] - x[..., 0] * y[..., 2],
                  x[..., 0] * y[..., 1] - x[..., 1] * y[..., 0]], axis=-1)
    return np.concatenate([d, m], axis=-1)


def moved_line(md: MotionData, idx: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """Line of the moving segments ``(B, 2, 3)`` as vector polynomials ``(B, 6, n)``."""
    return np.einsum("bojn,bj->bon", md.lines[idx], plucker(seg))


def moving_segments(md: MotionData, idx: np.ndarray, seg: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Moving segments ``(B, 2, 3)`` at the design's times ``t`` ``(B, T)`` (inf allowed) ->
    ``(B, T, 2, 3)``."""
    return segments_at(md, idx, seg, md.to_s(t))


def segments_at(md: MotionData, idx: np.ndarray, seg: np.ndarray, s: np.ndarray) -> np.ndarray:
    """:func:`moving_segments` at parameters ``s`` of ``md`` (NaN where the pose vanishes).

    Evaluates the pose ``R(s)`` (degree k, :func:`poly.evaluate_pose`: exact at inf) and acts
    on the points, not ``X(s) / N(s)``: near a fast turn ``N = |P|^2`` has twice the
    cancellation of ``P`` (1e-18 of its coefficients, i.e. all digits lost, where ``P`` keeps
    half of them).
    """
    pose = poly.evaluate_pose(md.motions[idx][:, None], s)  # (B, T, 8)
    with np.errstate(divide="ignore", invalid="ignore"):
        return dq.transform_points(pose[:, :, None, :], seg[:, None])


def _critical_times(md: MotionData, idx: np.ndarray, fixed: np.ndarray, moving: np.ndarray):
    """Real parts of the critical points (in ``s``) of the nine Lumelsky cases, ``(B, K)``
    (NaN = none)."""
    n_items = len(idx)
    nrm = md.norm[idx]
    dn = pder(nrm)
    pa = plucker(fixed)
    la, ma = pa[:, :3], pa[:, 3:]
    lb = moved_line(md, idx, moving)
    lbt, mbt = lb[:, :3], lb[:, 3:]
    om = np.einsum("bc,bcn->bn", la, mbt) + np.einsum("bc,bcn->bn", ma, lbt)
    big = []  # the five cases of degree 6k-1 (before cancellation)
    g = vsq(vcross(la[..., None], lbt))  # line-line: Om^2 / |l_A x l_B|^2
    big.append(2.0 * pmul(pder(om), g) - pmul(om, pder(g)))  # Om factored out: its roots are
    # intersection times, added below as candidates of their own.
    for x in (moving[:, 0], moving[:, 1]):  # moving endpoint vs fixed line A
        xh = np.concatenate([x, np.ones((n_items, 1))], 1)
        xt = np.einsum("bcjn,bj->bcn", md.points[idx], xh)
        f = vsq(vcross(xt, la[..., None]) - nrm[:, None, :] * ma[..., None])
        big.append(pmul(pder(f), nrm) - 2.0 * pmul(f, dn))
    for y in (fixed[:, 0], fixed[:, 1]):  # fixed endpoint vs moving line B (|l_B(t)| ∝ N)
        f = vsq(vcross(y[..., None], lbt) - mbt)
        big.append(pmul(pder(f), nrm) - 2.0 * pmul(f, dn))
    small = []  # endpoint-endpoint: |P x - y P + 2 D|^2 / N
    p, d = md.motions[idx][..., :4], md.motions[idx][..., 4:]
    for x in (moving[:, 0], moving[:, 1]):
        px = dq.qmul(p, np.concatenate([np.zeros((n_items, 1)), x], 1)[:, None])
        for y in (fixed[:, 0], fixed[:, 1]):
            yp = dq.qmul(np.concatenate([np.zeros((n_items, 1)), y], 1)[:, None], p)
            f = vsq(np.swapaxes(px - yp + 2.0 * d, -1, -2))
            small.append(pmul(pder(f), nrm) - pmul(f, dn))
    # The top coefficient of every F'G - FG' cancels identically: drop it.
    roots = [
        poly.real_poly_roots(np.stack(big, 1)[..., :-1], rtol=TOL.zero).real.reshape(n_items, -1),
        poly.real_poly_roots(np.stack(small, 1)[..., :-1], rtol=TOL.zero).real.reshape(n_items, -1),
        poly.real_poly_roots(om, rtol=TOL.zero).real,
    ]
    return np.concatenate(roots, axis=1)


def with_home(roots: np.ndarray) -> np.ndarray:
    """Candidate parameters ``(B, K+1)``: inf (home) first, then the roots (NaN = at inf)."""
    return np.concatenate([np.full((len(roots), 1), np.inf),
                           np.where(np.isnan(roots), np.inf, roots)], axis=1)


def min_distance_batch(
    md: MotionData, idx: np.ndarray, fixed: np.ndarray, moving: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Exact minimum over the cycle of ``dist(fixed, R(t) moving)`` for items ``(B,)``.

    ``idx`` ``(B,)`` selects each item's motion in ``md``; ``fixed``/``moving`` ``(B, 2, 3)`` in
    link i's/link j's home frame (base coordinates at t = inf). Returns ``(dist (B,), t (B,))``,
    ``t = inf`` where the minimum is attained at the home configuration.
    """
    cand = with_home(chart_roots(md, lambda m: _critical_times(m, idx, fixed, moving)))
    seg = segments_at(md, idx, moving, cand)
    dist = segment_distance(fixed[:, None, 0], fixed[:, None, 1], seg[..., 0, :], seg[..., 1, :])
    best = np.argmin(dist, axis=1)
    rows = np.arange(len(idx))
    return dist[rows, best], md.to_t(cand[rows, best])


def min_distance(
    motion: np.ndarray, fixed: np.ndarray, moving: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Exact min distance over ``t in R u {inf}`` between fixed segments and segments moved by
    one motion polynomial ``motion`` ``(k+1, 8)`` (k >= 1). ``fixed``, ``moving``: ``(B, 2, 3)``
    or ``(2, 3)``. Returns ``(dist, t)`` with the batch shape (``t = inf`` at home)."""
    motion = poly.as_poly(motion, "motion")
    if motion.ndim != 2 or motion.shape[0] < 2:
        raise ValueError(f"motion must be one polynomial (k+1, 8) with k >= 1, got {motion.shape}")
    fixed, moving = np.asarray(fixed, np.float64), np.asarray(moving, np.float64)
    if fixed.shape[-2:] != (2, 3) or moving.shape != fixed.shape:
        raise ValueError(f"segments must both be (..., 2, 3), got {fixed.shape}, {moving.shape}")
    shape = fixed.shape[:-2]
    f2, m2 = fixed.reshape(-1, 2, 3), moving.reshape(-1, 2, 3)
    dist, t = min_distance_batch(motion_data(motion[None]), np.zeros(len(f2), int), f2, m2)
    return dist.reshape(shape), t.reshape(shape)
