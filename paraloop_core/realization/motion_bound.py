"""Rigorous continuous-motion bound of a relative link motion (used by carving, grounding and
verification).

**Continuous-motion bound** (:func:`motion_bound`). Write ``theta = pi (u - 1/2)`` and
``Q(theta) = cos(theta)^k R(tan theta)`` for the relative motion ``R`` of degree k: each
coordinate of ``Q`` is a trigonometric polynomial of degree k (same pose as ``R(t)``). With
``P`` its primal part, the angular velocity is ``w = 2 vec(P' P~) / |P|^2`` and a reference point
``c`` moves with ``X' = (N' B - N B') / B^2`` (``N`` numerator of ``R(c)``, ``B = |P|^2``); the
numerators are trigonometric polynomials of degree ``2k`` and ``4k``. Bernstein's inequality
``max|T'| <= deg max|T|`` (valid for vector-valued T) bounds every numerator on a cell of width
``h_c`` about a sample by ``|T(sample)| + (h_c/2) deg max|T|`` and ``B >= b_lo = B(sample) -
(h_c/2) |B'(sample)| - (h_c/2)^2 (2k)^2 max B / 2`` (so ``B^2 >= b_lo^2``), where
``max|T| <= max_samples|T| / (1 - deg h_c/2)``. Cells are subdivided where ``B`` dips.
Hence any point within ``radius`` of ``c`` moves at most ``omega * radius + speed`` per unit
theta inside each cell: an upper bound, never an estimate. Integrating it gives how far such
a point can move between time samples; sweeps are dilated by that distance, so carving is
collision-free for the continuous motion.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from paraloop_core.algebra import dq, poly
from paraloop_core.errors import FabricationError
from paraloop_core.linkage import loops


@dataclass(frozen=True)
class MotionBound:
    """Per-cell speed bounds of one relative motion over the cycle (``theta`` in
    ``[-pi/2, pi/2)``, cells between ``edges`` ``(K+1,)``, finer where the motion turns fast):
    ``omega`` ``(K,)`` bounds the angular speed, ``speed`` ``(K,)`` the speed of ``center``
    ``(3,)`` (home frame of the moving link), both per unit theta (times pi: per unit u)."""

    omega: np.ndarray
    speed: np.ndarray
    center: np.ndarray
    edges: np.ndarray

    def rate(self, radius: float) -> np.ndarray:
        """Speed bound ``(K,)`` per unit theta for all points within ``radius`` of ``center``."""
        return self.omega * radius + self.speed

    def cumulative(self, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Cell edges ``(K+1,)`` in theta and the integrated bound ``(K+1,)`` at them."""
        widths = np.diff(self.edges)
        return self.edges, np.concatenate([[0.0], np.cumsum(self.rate(radius) * widths)])


def _trig(c: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``Q(theta)`` and ``Q'(theta)`` ``(T, 8)`` for a polynomial ``(k+1, 8)`` (see module)."""
    k = c.shape[0] - 1
    s, co = np.sin(theta)[:, None], np.cos(theta)[:, None]
    sp, cp = [s**m for m in range(k + 1)], [co**m for m in range(k + 1)]  # each power once
    q = np.zeros(theta.shape + (8,))
    dq_ = np.zeros_like(q)
    for m in range(k + 1):  # tiny degree
        q += sp[m] * cp[k - m] * c[m]
        d = m * sp[max(m - 1, 0)] * cp[k - m + 1] if m > 0 else 0.0
        if m < k:
            d = d - (k - m) * sp[m + 1] * cp[k - m - 1]
        dq_ += d * c[m]
    return q, dq_


def _numerators(c: np.ndarray, x: np.ndarray, th: np.ndarray) -> tuple[np.ndarray, ...]:
    """``B = |P|^2``, ``|B'|``, ``|2 P' P~|`` and ``|N' B - N B'|`` ``(T,)`` at ``th``."""
    q, qd = _trig(c, th)
    p, d, pd, dd = q[:, :4], q[:, 4:], qd[:, :4], qd[:, 4:]
    pc, pdc = dq.qconj(p), dq.qconj(pd)
    b = np.sum(p * p, -1)
    bd = 2.0 * np.sum(p * pd, -1)
    aw = 2.0 * np.linalg.norm(dq.qmul(pd, pc)[:, 1:], axis=-1)
    px = dq.qmul(p, x)
    n = (dq.qmul(px, pc) + 2.0 * dq.qmul(d, pc))[:, 1:]
    nd = (dq.qmul(dq.qmul(pd, x), pc) + dq.qmul(px, pdc)
          + 2.0 * dq.qmul(dd, pc) + 2.0 * dq.qmul(d, pdc))[:, 1:]
    return b, np.abs(bd), aw, np.linalg.norm(nd * b[:, None] - n * bd[:, None], axis=-1)


#: Narrowest cell (radians of theta) before a motion counts as too close to a singular pose.
_MIN_WIDTH = 1e-13
#: Most samples :func:`adaptive_params` hands out (memory: a few arrays of this length).
_MAX_SAMPLES = 5_000_000
#: Tightening (splitting cells whose Bernstein slack dominates) stops at this width / count.
_TIGHT_WIDTH = 1e-7
_TIGHT_CELLS = 1 << 16


def motion_bound(joint_factors: np.ndarray, i: int, j: int, center: np.ndarray,
                 cells: int = 4096, affine: tuple[float, float] | None = None) -> MotionBound:
    """Rigorous speed bounds of link j moving in link i's home frame (module docstring).

    ``center`` ``(3,)`` is a point of link j (home frame, design units). The global maxima come
    from ``cells`` uniform samples; cells are then subdivided (adaptively, where the motion
    turns fast) until the norm ``|P|^2`` keeps half its sampled value on every cell. With
    ``affine = (a, b)`` the bound is for the parameter ``s`` of ``t = a s + b`` (the same motion;
    a well-centred ``s`` needs far fewer cells, see :func:`factor.conditioning_batch`)."""
    c = loops.relative_motion(np.asarray(joint_factors, float), i, j)
    if affine is not None:
        c = poly.reparametrize(c, *affine)
    k = c.shape[0] - 1
    x = np.concatenate([[0.0], np.asarray(center, float)])
    h = np.pi / cells
    if 4 * k * h / 2 >= 0.5:
        raise ValueError(f"cells must exceed {int(4 * k * np.pi)} for degree {k}, got {cells}")
    th = -np.pi / 2 + (np.arange(cells) + 0.5) * h
    b, bd, aw, nv = _numerators(c, x, th)

    def gmax(v: np.ndarray, deg: int) -> float:
        return float(np.max(v)) / (1.0 - deg * h / 2)  # Bernstein + sampling

    mb, ma, mn = gmax(b, 2 * k), gmax(aw, 2 * k), gmax(nv, 4 * k)
    left = np.linspace(-np.pi / 2, np.pi / 2, cells + 1)[:-1]
    width = np.full(cells, h)
    while True:
        # Taylor to second order with Bernstein's max|B''| <= (2k)^2 max B: B >= b_lo on the
        # cell, so B^2 >= b_lo^2 (first order alone would need needle cells near dips of B)
        b_lo = b - width / 2 * bd - (width / 2) ** 2 / 2 * (2 * k) ** 2 * mb
        # Split where B may lose half its value, or where the Bernstein slack of a numerator
        # exceeds its sampled value (the bound would be loose there: slow certificates).
        loose = (b_lo <= 0.5 * b) | (
            ((width / 2 * 2 * k * ma > aw) | (width / 2 * 4 * k * mn > nv))
            & (width > _TIGHT_WIDTH) & (width.size < _TIGHT_CELLS))
        if not loose.any():
            break
        if width[loose].min() < _MIN_WIDTH or width.size > 1 << 22:
            raise FabricationError(
                f"relative motion of links {i}, {j} passes too close to a singular pose to "
                "bound its speed", "bad-parameters")
        # split the loose cells in four; recompute only those
        sub = (left[loose][:, None] + width[loose][:, None] * np.arange(4) / 4).ravel()
        sub_w = np.repeat(width[loose] / 4, 4)
        new = _numerators(c, x, sub + sub_w / 2)
        keep = ~loose
        left = np.concatenate([left[keep], sub])
        width = np.concatenate([width[keep], sub_w])
        b, bd, aw, nv = (np.concatenate([v[keep], w]) for v, w in zip((b, bd, aw, nv), new,
                                                                      strict=True))
        order = np.argsort(left)
        left, width, b, bd, aw, nv = (v[order] for v in (left, width, b, bd, aw, nv))
    omega = (aw + width / 2 * 2 * k * ma) / b_lo
    speed = (nv + width / 2 * 4 * k * mn) / b_lo**2
    edges = np.append(left, np.pi / 2)
    return MotionBound(omega, speed, np.asarray(center, float), edges)


def _lam(edges: np.ndarray, cum: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Integrated bound at any theta, extended periodically (period pi)."""
    turns = np.floor((theta + np.pi / 2) / np.pi)
    return np.interp(theta - turns * np.pi, edges, cum) + turns * cum[-1]


def displacement_bounds(mb: MotionBound, radius: float, u: np.ndarray) -> np.ndarray:
    """For sorted samples ``u`` ``(T,)`` in ``[0, 1)``: ``(T,)`` bound on how far any point
    within ``radius`` of ``mb.center`` moves between sample k and any time closer (in u) to
    sample k than to its neighbours (cyclic): centre path plus ``min(radius * turned angle,
    2 radius)`` (a rotation moves a point by at most the chord, at most the diameter)."""
    th = np.pi * (np.asarray(u, float) - 0.5)
    nxt = np.append(th[1:], th[0] + np.pi)
    prv = np.insert(th[:-1], 0, th[-1] - np.pi)

    def halves(bound: MotionBound) -> np.ndarray:  # (2, T): integrated bound back / forward
        edges, cum = bound.cumulative(radius)
        lam = _lam(edges, cum, th)
        return np.stack([lam - _lam(edges, cum, (th + prv) / 2),
                         _lam(edges, cum, (th + nxt) / 2) - lam])

    zero = np.zeros_like(mb.omega)
    path = halves(replace(mb, omega=zero))
    move = path + np.minimum(halves(replace(mb, speed=zero)), 2.0 * radius)
    # differences of cumulative sums: allow their round-off so the bound stays an upper bound
    slack = 16.0 * np.finfo(float).eps * (mb.cumulative(radius)[1][-1] + radius)
    return move.max(axis=0) + slack


def adaptive_params(mb: MotionBound, radius: float, delta: float) -> np.ndarray:
    """Samples ``u`` ``(T,)`` such that every time is within moved distance ``delta`` of a
    sample, for all points within ``radius`` of ``mb.center`` (equal steps of the bound)."""
    edges, cum = mb.cumulative(radius)
    n = cum[-1] / (2.0 * delta)
    if not n <= _MAX_SAMPLES:  # also NaN: the bound is too loose to sample (near singular)
        raise FabricationError(
            f"the motion passes too close to a singular pose: its speed bound would need "
            f"{n:.3g} samples (cap {_MAX_SAMPLES:g}); choose another mu or loop", "bad-parameters")
    n = max(int(np.ceil(n)), 8)
    th = np.interp((np.arange(n) + 0.5) * cum[-1] / n, cum, edges)
    return th / np.pi + 0.5


def chain_displacement_bounds(joint_factors: np.ndarray, a: int, b: int, center: np.ndarray,
                              radius: float, u: np.ndarray) -> np.ndarray:
    """Like :func:`displacement_bounds` for the motion of link b in link a's home frame, from
    its joint factors (:func:`loops.relative_chain`) instead of a speed bound: ``(T,)``.

    Factor m at ``theta`` is ``sin(theta) + cos(theta) (t - h_m)`` scaled, i.e. the pose at
    ``t = tan theta`` (no infinity), a point of the plane ``span(1, h_m)`` whose angle is
    monotone in theta; over a half cell (< pi of theta) its half angle sweeps ``delta_m`` < pi,
    the angle between the ends (:func:`chain_sweep`). Exact angles: no blow-up where the
    motion passes close to a singular pose (a fast turn), unlike the speed bound.
    """
    chain = loops.relative_chain(np.asarray(joint_factors, float), a, b)  # (k, 2, 8)
    axes = loops.factor_axes(chain[:, 0])
    th = np.pi * (np.asarray(u, float) - 0.5)
    nxt = np.append(th[1:], th[0] + np.pi)
    prv = np.insert(th[:-1], 0, th[-1] - np.pi)

    def primal(x: np.ndarray) -> np.ndarray:  # (k, T, 8), unit primal part
        q = np.sin(x)[None, :, None] * chain[:, None, 1] + \
            np.cos(x)[None, :, None] * chain[:, None, 0]
        return q / np.linalg.norm(q[..., :4], axis=-1, keepdims=True)

    q0 = primal(th)
    move, y = chain_sweep(q0, [primal((th + prv) / 2), primal((th + nxt) / 2)], axes,
                          np.asarray(center, float)[None, None], radius)
    size = np.abs(y).max() + radius + np.abs(axes[:, 3:]).sum()
    return move[:, 0] * (1.0 + 1e-12) + 1e-12 * size  # rounding of the points and angles


def chain_sweep(centre: np.ndarray, ends: list[np.ndarray], axes: np.ndarray,
                points: np.ndarray, radius: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """How far points move over cells of a product of rotation factors, and where they are.

    ``centre`` ``(k, C, 8)``: the k factors (outermost first, unit primal parts, continuous
    along each cell) at the cell centres; ``ends`` their values at the cell ends; ``axes``
    ``(k, 6)`` (or ``(k, C, 6)``, per cell) their unit Plücker axes; ``points`` ``(C or 1, P,
    3)``. Each factor's half angle
    sweeps ``delta_m`` (< pi), the angle between centre and end (monotone: a line in its plane
    ``span(1, axis)``); telescoping the product, a point within ``radius`` of a given one moves
    at most ``sum_m 2 sin(min(delta_m, pi/2)) (dist(y_m, axis_m) + radius)`` (``y_m``: the point
    carried by the inner factors at the centre). Returns ``(move (C, P), moved (C, P, 3))``.

    Written per component (arrays ``(comp, k, C)``: long inner loops; the certificate's branch
    and bound spends its time here).
    """
    c = np.moveaxis(centre, -1, 0)  # (8, k, C)
    delta = np.zeros(c.shape[1:])
    for end in ends:  # half angle swept: end * conj(centre), the rotation from centre to end
        e = np.moveaxis(end, -1, 0)
        w = e[0] * c[0] + e[1] * c[1] + e[2] * c[2] + e[3] * c[3]
        vx = -e[0] * c[1] + e[1] * c[0] - e[2] * c[3] + e[3] * c[2]
        vy = -e[0] * c[2] + e[1] * c[3] + e[2] * c[0] - e[3] * c[1]
        vz = -e[0] * c[3] - e[1] * c[2] + e[2] * c[1] + e[3] * c[0]
        delta = np.maximum(delta, np.arctan2(np.sqrt(vx * vx + vy * vy + vz * vz), w))
    chord = 2.0 * np.sin(np.minimum(delta, np.pi / 2))[..., None]  # (k, C, 1)
    ax = np.moveaxis(axes, -1, 0)[..., None]  # (6, k, 1) or (6, k, C, 1)
    y = np.moveaxis(np.broadcast_to(points, (c.shape[2],) + points.shape[1:]), -1, 0)
    move = np.zeros(y.shape[1:])  # y (3, C, P)
    for m in reversed(range(c.shape[1])):  # innermost factor first (k <= 3)
        a0, a1, a2, m0, m1, m2 = ax[:, m]
        cx, cy, cz = y[1] * a2 - y[2] * a1 - m0, y[2] * a0 - y[0] * a2 - m1, \
            y[0] * a1 - y[1] * a0 - m2
        move += chord[m] * (np.sqrt(cx * cx + cy * cy + cz * cz) + radius)
        # y <- (P y P~ + 2 D P~) / |P|^2 of the factor P + eps D, P = (w, v), D = (d0, dv):
        # ((w^2 - |v|^2) y + 2 (v.y) v + 2 w v x y + 2 (w dv - d0 v - dv x v)) / |P|^2
        w, v0, v1, v2, d0, e0, e1, e2 = c[:, m, :, None]
        vv = v0 * v0 + v1 * v1 + v2 * v2
        s, w2 = w * w - vv, 2.0 * w
        vy2 = 2.0 * (v0 * y[0] + v1 * y[1] + v2 * y[2])
        y = np.stack([
            s * y[0] + vy2 * v0 + w2 * (v1 * y[2] - v2 * y[1])
            + 2.0 * (w * e0 - d0 * v0 - (e1 * v2 - e2 * v1)),
            s * y[1] + vy2 * v1 + w2 * (v2 * y[0] - v0 * y[2])
            + 2.0 * (w * e1 - d0 * v1 - (e2 * v0 - e0 * v2)),
            s * y[2] + vy2 * v2 + w2 * (v0 * y[1] - v1 * y[0])
            + 2.0 * (w * e2 - d0 * v2 - (e0 * v1 - e1 * v0))]) / (w * w + vv)
    return move, np.moveaxis(y, 0, -1)


def try_motion_bound(joint_factors: np.ndarray, i: int, j: int,
                     center: np.ndarray) -> MotionBound | None:
    """:func:`motion_bound`, or None where the motion passes too close to a singular pose for
    a speed bound (:func:`sound_displacement_bounds` then uses the joint angles alone)."""
    try:
        return motion_bound(joint_factors, i, j, center)
    except FabricationError:
        return None


def sound_displacement_bounds(joint_factors: np.ndarray, a: int, b: int, center: np.ndarray,
                              radius: float, u: np.ndarray, bound: MotionBound | None
                              ) -> np.ndarray:
    """``(T,)``: the smaller of :func:`displacement_bounds` (speed ``bound`` of
    :func:`try_motion_bound`) and :func:`chain_displacement_bounds` (joint angles, finite near
    a singular pose; alone where ``bound`` is None). Design units."""
    chain = chain_displacement_bounds(joint_factors, a, b, center, radius, u)
    return chain if bound is None else np.minimum(displacement_bounds(bound, radius, u), chain)


def sound_params(joint_factors: np.ndarray, a: int, b: int, center: np.ndarray, radius: float,
                 delta: float) -> np.ndarray:
    """Samples ``u`` ``(T,)`` (sorted, in [0, 1)) such that every time is within moved distance
    ``delta`` of a sample, for all points within ``radius`` of ``center`` (link b in link a's
    home frame): :func:`adaptive_params` of the speed bound where that is finite enough, else
    (a motion close to a singular pose) cells split in two until the joint-angle bound
    (:func:`chain_displacement_bounds`) of every sample is at most ``delta``. Raises
    FabricationError past :data:`_MAX_SAMPLES` samples."""
    try:
        return adaptive_params(motion_bound(joint_factors, a, b, center), radius, delta)
    except FabricationError:
        pass
    u = np.arange(256) / 256.0
    while True:
        move = chain_displacement_bounds(joint_factors, a, b, center, radius, u)
        bad = move > delta
        if not bad.any():
            return u
        # a sample covers the half cells on both sides: split both cells of a bad sample
        split = bad | np.roll(bad, -1)  # cell i runs from u[i] to u[i + 1] (cyclic)
        mids = (u + np.append(u[1:], u[0] + 1.0)) / 2.0 % 1.0
        u = np.unique(np.concatenate([u, mids[split]]))
        if len(u) > _MAX_SAMPLES:
            raise FabricationError(
                f"the motion of link {b} relative to link {a} needs more than {_MAX_SAMPLES:g} "
                f"samples to move at most {delta:.3g} between them; use a coarser resolution",
                "bad-parameters")
