"""Drive analysis of a loop with one joint as motor (paper Sec. 6.4): speeds, motor, torque.

Joint angles as :func:`loops.joint_angles` (``dphi_i/dt = 2 s_i b_i / ((t - a_i)^2 + b_i^2)``,
``a_i + i b_i`` the norm root of factor i). Motor joint m: motor angle ``theta = 2 atan2(b_m,
a_m - t)`` in ``[0, 2 pi)``, its turn since home (t = inf) as t increases; gear ratios
``g_j = dphi_j/dtheta``, ``g_j' = dg_j/dtheta`` in closed form. At motor speed ``omega(theta)``
joint j moves at ``g_j omega`` (rad/s, signed), accelerating at ``g_j' omega^2 + g_j domega/dt``
(rad/s^2). Formulas, sampling, methods, units and limits: docs/realization.md, Drive analysis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from paraloop_core.algebra import dq, poly
from paraloop_core.linkage import loops
from paraloop_core.tolerance import TOL

TWO_PI = 2.0 * np.pi
#: A joint of the resting link stays the motor unless another joint's worst peak speed ratio
#: is smaller by more than this factor (a grounded motor needs no moving cables).
PREFER_FACTOR = 1.5
SAMPLES = 256  #: default samples per cycle of each sample family (:func:`motor_angles`)
#: Worst peak speed ratio (:func:`smooth_drive_penalty`) above which one motor cannot hold a
#: loop: in the slow stretch of its turn another joint turns this many times faster, so the
#: motor's least play or lag moves the links that much more and they swing under gravity.
#: Measured with the physics check (0.5 ms steps) on the printed random designs 62000 - 62047:
#: all 12 loops up to 31 completed their cycle within 12 % of the pose tolerance; of the two
#: at 44 and 46 the first lost it (1.7 x the tolerance), and 31 of the 34 from 62 up lost it
#: (the ratio is the motion's: the same for all nine loops);
#: the five examples are at 2 - 5. Past this ratio the export says to turn the loop by hand
#: and the physics check does so (``physics.simulate(hand=True)``).
HOLD_RATIO = 30.0
_CHAIN = np.where(np.arange(6)[:, None] <= 3, np.tri(6, k=-1), -np.tri(6).T)  # link_poses


@dataclass(frozen=True)
class ConstantSpeed:
    """See :func:`constant_speed`; arrays ``(N,)`` / ``(N, 6)``, peaks ``(6,)`` per joint."""

    motor: int
    cycle_time: float  # s
    theta: np.ndarray  # motor angles, rad (time = theta / omega)
    t: np.ndarray  # loop parameters
    velocity: np.ndarray  # rad/s, signed
    acceleration: np.ndarray  # rad/s^2
    peak_speed_ratio: np.ndarray  # max|v_j| / mean|v_j| (mean = 2 pi / cycle_time), exact
    peak_accel: np.ndarray  # max|a_j|, rad/s^2, exact


@dataclass(frozen=True)
class MotorChoice:
    """See :func:`recommend_motor`."""

    motor: int
    worst_speed_ratio: float  # of the chosen motor: max over joints of peak_speed_ratio
    peak_speed_ratio: np.ndarray  # (6 motors, 6 joints)
    preferred: tuple[int, int]  # the resting link's joints
    reason: str


@dataclass(frozen=True)
class MotorTorque:
    """See :func:`motor_torque`."""

    motor: int
    theta: np.ndarray  # (N,) rad
    t: np.ndarray
    torque: np.ndarray  # (N,) N m, positive along increasing theta
    peak_torque: float  # max|torque|, N m
    moving_mass_kg: float  # every link but the resting one


def norm_roots(jf: np.ndarray, batched: bool = False) -> tuple[np.ndarray, ...]:
    """``(jf, a, b)``: checked loop ``(6, 8)`` (``(..., 6, 8)`` if ``batched``) and the norm
    roots ``a +- i b`` ``(..., 6)`` of its factors (``b > 0``)."""
    jf = np.asarray(jf, dtype=np.float64)
    if jf.shape[-2:] != (6, 8) or (jf.ndim != 2 and not batched):
        raise ValueError(f"joint factors must have shape {'(..., 6, 8)' if batched else '(6, 8)'}"
                         f", got {jf.shape}")
    if not np.isfinite(jf).all():
        raise ValueError("joint factors must be finite")
    b = np.linalg.norm(jf[..., 1:4], axis=-1)
    if (b <= TOL.zero * (1.0 + np.abs(jf[..., 0]))).any():
        raise ValueError("a joint factor has no rotation axis (zero vector part)")
    return jf, jf[..., 0], b


def check_index(name: str, value: int, lo: int, hi: int) -> int:
    """``value`` as an int in ``lo..hi`` (no bool), else ValueError naming ``name``."""
    ok = isinstance(value, (int, np.integer)) and not isinstance(value, bool)
    if not (ok and lo <= value <= hi):
        raise ValueError(f"{name} must be an integer in {lo}..{hi}, got {value!r}")
    return int(value)


def check_positive(name: str, value: float) -> float:
    """``value`` as a positive finite float, else ValueError naming ``name``."""
    v = float(value) if isinstance(value, (int, float, np.number)) else np.nan
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return v


def _array(name: str, x: np.ndarray, shape: tuple[int, ...] | None) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if (x.shape != shape if shape else x.ndim != 1) or not np.isfinite(x).all():
        raise ValueError(f"{name} must be finite, of shape {shape or '(N,)'}, got {x.shape}")
    return x


def joint_rates(jf: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact ``dphi/dt`` and ``d2phi/dt2 = -4 s b (t - a) / D^2`` ``(T, 6)`` (rad per unit t,
    per t^2) of :func:`loops.joint_angles` at parameters ``t`` ``(T,)``; 0 at t = +-inf."""
    _, a, b = norm_roots(jf)
    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    if t.ndim != 1 or np.isnan(t).any():
        raise ValueError(f"t must be a 1-D array without NaN, got shape {t.shape}")
    fin, s = np.isfinite(t)[:, None], loops.JOINT_SIGN
    u = np.where(fin, t[:, None] - a, 0.0)
    h = np.hypot(u, b)  # b/h, u/h in [-1, 1]: no overflow for finite t
    return (np.where(fin, 2.0 * s * (b / h) / h, 0.0),
            np.where(fin, -4.0 * s * (b / h) * (u / h) / h**2, 0.0))


def gear(a: np.ndarray, b: np.ndarray, m: int, theta: np.ndarray) -> tuple[np.ndarray, ...]:
    """``t`` ``(T,)``, ``g``, ``g'`` ``(T, 6)`` of motor m at motor angles ``theta`` ``(T,)``
    (views of :func:`gear_rows`)."""
    t, g, gp = gear_rows(a, b, m, theta)
    return t, g.T, gp.T


def gear_rows(a: np.ndarray, b: np.ndarray, m: int, theta: np.ndarray
              ) -> tuple[np.ndarray, ...]:
    """``t`` ``(T,)``, ``g``, ``g'`` ``(6, T)`` (joints first: long inner loops).

    With ``s = t - a_m = -b_m cot(theta/2)`` and ``h_j^2 = (s - a_j + a_m)^2 + b_j^2``:
    ``g_j = sign_j b_j h_m^2 / (b_m h_j^2)`` (``loops.JOINT_SIGN``). All of it is scaled by
    ``h_m = b_m / |sin(theta/2)|`` (``c = s / h_m``, ``e = b_m / h_m`` in [-1, 1]): no
    overflow, no square root, home (theta = 0, t = -inf) included."""
    half = 0.5 * np.asarray(theta, dtype=np.float64)
    sn, cs = np.sin(half), np.cos(half)
    with np.errstate(divide="ignore"):  # theta = 0: home, t = -inf
        t = np.where(sn == 0.0, -np.inf, a[m] - b[m] * cs / sn)
    e = np.abs(sn)
    c = -cs * np.copysign(1.0, sn)
    ih = e / b[m]  # 1 / h_m
    delta, bm = (a - a[m])[:, None], b[:, None]
    u = c - delta * ih
    bi = bm * ih
    u *= u
    bi *= bi
    u += bi
    rho = np.divide(1.0, u, out=u)  # D_m / D_j = h_m^2 / h_j^2
    # N_j / D_j = (delta (c^2 - e^2) + (b_m^2 - b_j^2 - delta^2) c / h_m) rho
    nd = delta * (c * c - e * e)
    nd += (b[m] ** 2 - bm**2 - delta**2) * (c * ih)
    nd *= rho
    g = (loops.JOINT_SIGN * (b / b[m]))[:, None] * rho
    nd *= g
    nd *= -1.0 / b[m]
    return t, g, nd


def _ratio_critical(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``s = t - a_m`` ``(..., 6, 6, 3)`` [motor, joint] where |g_j| may peak: N_j = 0, inf."""
    am, bm = a[..., :, None], b[..., :, None]
    delta = a[..., None, :] - am
    b1 = bm**2 - b[..., None, :] ** 2 - delta**2
    q = -0.5 * (b1 + np.where(b1 >= 0, 1.0, -1.0) * np.sqrt(b1**2 + 4 * delta**2 * bm**2))
    with np.errstate(divide="ignore", invalid="ignore"):  # 0/0 (delta = 0): inf is a candidate
        s = np.stack([q / delta, -delta * bm**2 / q, np.full_like(q, np.inf)], axis=-1)
    return np.where(np.isnan(s), np.inf, s)


def peak_speed_ratios(jf: np.ndarray) -> np.ndarray:
    """Exact ``max |g_j|`` ``(..., 6, 6)`` [motor, joint] of loops ``(..., 6, 8)``: joint j's
    peak over mean speed with motor m at constant speed (closed form, ~0.1 ms per call)."""
    _, a, b = norm_roots(jf, batched=True)
    s = _ratio_critical(a, b)
    am, bm, bj = a[..., :, None, None], b[..., :, None, None], b[..., None, :, None]
    fin = np.isfinite(s)
    sf = np.where(fin, s, 0.0)
    hj = np.hypot(sf - (a[..., None, :, None] - am), bj)
    return ((bj / bm) * np.where(fin, (np.hypot(sf, bm) / hj) ** 2, 1.0)).max(axis=-1)


def _conv(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Products of polynomials ``(..., p)``, ``(..., r)`` (ascending) -> ``(..., p + r - 1)``."""
    out = np.zeros(x.shape[:-1] + (x.shape[-1] + y.shape[-1] - 1,))
    for k in range(y.shape[-1]):  # a loop over coefficients, not samples
        out[..., k:k + x.shape[-1]] += x * y[..., k:k + 1]
    return out


def _accel_critical(a: np.ndarray, b: np.ndarray, m: int) -> np.ndarray:
    """t where |g_j'| may peak (real parts: spurious candidates only add samples): roots of
    the six numerators of ``d g_j' / ds`` (degree <= 5, ``s = t - a_m``), all at once."""
    # joints with the same norm root (angle-symmetric loops pair them) up to rounding share
    # their roots: computed once, so rounding cannot split them into two samples
    near = np.abs(a[:, None] - a) + np.abs(b[:, None] - b) <= 1e-12 * (np.abs(a) + b).max()
    first = ~np.tril(near, -1).any(axis=1)
    a_j, b_j = a[first], b[first]
    d, bm2, bj2, one = a_j - a[m], b[m] ** 2, b_j**2, np.ones(len(a_j))
    nd = _conv(np.stack([-d * bm2, bm2 - bj2 - d * d, d], -1), np.array([bm2, 0.0, 1.0]))
    q = (_conv(nd[:, 1:] * np.arange(1.0, 5.0), np.stack([d * d + bj2, -2.0 * d, one], -1))
         - 2.0 * _conv(nd, np.stack([-2.0 * d, 2.0 * one], -1)))
    big = np.abs(q) > 1e-13 * np.maximum(np.abs(q).max(axis=1, keepdims=True), 1e-300)
    deg = np.where(big.any(axis=1), q.shape[1] - 1 - np.argmax(big[:, ::-1], axis=1), 0)
    out = [np.zeros(0)]
    for n in np.unique(deg[deg >= 1]):  # at most 5 degrees: companion matrices per degree
        c = q[deg == n, : n + 1]
        if n == 1:
            out.append(a[m] - c[:, 0] / c[:, 1])
            continue
        comp = np.zeros((len(c), n, n))
        comp[:, np.arange(1, n), np.arange(n - 1)] = 1.0
        comp[:, :, -1] -= c[:, :-1] / c[:, -1:]
        out.append(a[m] + np.linalg.eigvals(comp[:, ::-1, ::-1]).real.ravel())
    return np.concatenate(out)


def motor_angles(a: np.ndarray, b: np.ndarray, m: int, n: int) -> np.ndarray:
    """Sorted motor angles ``(N,)`` in ``[0, 2 pi)``: ``2 pi k / n``; per norm root the t where
    its joints turn uniformly (``a + b cot(pi (k + 1/2) / n)``, :func:`poly.cycle_parameters`);
    every critical point of each ``g_j`` and ``g_j'``. So no joint turns more than ``2 pi / n``
    between samples, each ``g_j``, ``g_j'`` is monotone there, and their extrema are samples."""
    t = np.concatenate([poly.cycle_parameters(a[:3], b[:3], n),
                        a[m] + _ratio_critical(a, b)[m].ravel(), _accel_critical(a, b, m)])
    th = np.mod(2.0 * np.arctan2(b[m], a[m] - t), TWO_PI)  # t = +-inf -> 0 (home)
    th = np.unique(np.concatenate([np.arange(n) * (TWO_PI / n), th[np.isfinite(th)]]))
    # near-duplicates add nothing (2 pi is home again); a step of 1e-12 rad would only turn
    # the rounding of the schedule's x into its acceleration (the slope of x over the step)
    return th[np.concatenate([[True], np.diff(th) > 1e-12]) & (TWO_PI - th > 1e-12)]


def constant_speed(jf: np.ndarray, motor: int, cycle_time: float, samples: int = SAMPLES,
                   theta: np.ndarray | None = None) -> ConstantSpeed:
    """Joint ``motor`` at constant ``omega = 2 pi / cycle_time`` (s): velocities ``g omega``,
    accelerations ``g' omega^2`` at :func:`motor_angles` (``samples`` per family) or at
    ``theta`` (rad); peaks always from the adaptive samples (exact maxima over the cycle)."""
    _, a, b = norm_roots(jf)
    m, ct = check_index("motor", motor, 0, 5), check_positive("cycle_time", cycle_time)
    grid = motor_angles(a, b, m, check_index("samples", samples, 8, 10**7))
    t, g, gp = gear(a, b, m, grid)
    w = TWO_PI / ct
    peak_ratio, peak_acc = np.abs(g).max(0), np.abs(gp).max(0) * w * w
    if theta is not None:
        grid = _array("theta", theta, None)
        t, g, gp = gear(a, b, m, grid)
    return ConstantSpeed(m, ct, grid, t, g * w, gp * w * w, peak_ratio, peak_acc)


def recommend_motor(jf: np.ndarray, resting_link: int,
                    prefer_factor: float = PREFER_FACTOR) -> MotorChoice:
    """The motor joint minimising the worst peak speed ratio over all joints, preferring the
    resting (grounded) link's joints ``resting_link - 1``, ``resting_link`` (mod 6) unless
    another is better by more than ``prefer_factor``; ``reason`` says why in words."""
    rest = check_index("resting_link", resting_link, 0, 5)
    factor = check_positive("prefer_factor", prefer_factor)
    ratios = peak_speed_ratios(norm_roots(jf)[0])
    worst = ratios.max(axis=1)
    pref = ((rest - 1) % 6, rest)
    bp, best = min(pref, key=lambda j: (worst[j], j)), int(np.argmin(worst))
    keep = worst[bp] <= max(factor, 1.0) * (1 + 1e-9) * worst[best]  # ties: the resting link
    motor, on = bp if keep else best, f"on link {rest}"
    if motor == bp:
        why = ("the best of all joints" if worst[bp] <= worst[best] else
               f"within {factor:g}x of the best, joint {best} ({worst[best]:.3g})")
        reason = f"joint {bp} ({on}, resting): worst peak speed ratio {worst[bp]:.3g}, {why}"
    else:
        reason = (f"joint {best}: worst peak speed ratio {worst[best]:.3g}, better by more than "
                  f"{factor:g}x than joint {bp} {on}, resting ({worst[bp]:.3g}); the motor "
                  "rides a moving link")
    return MotorChoice(int(motor), float(worst[motor]), ratios, pref, reason)


def smooth_drive_penalty(jf: np.ndarray, motor: int | None = None) -> float | np.ndarray:
    """Worst peak speed ratio (>= 1; 1 = all joints turn uniformly) of ``motor``, else of the
    best motor, of loops ``(..., 6, 8)``: ``(...)``, a float for one loop (~0.1 ms per call)."""
    worst = peak_speed_ratios(jf).max(axis=-1)
    out = worst.min(axis=-1) if motor is None else worst[..., check_index("motor", motor, 0, 5)]
    return float(out) if np.ndim(out) == 0 else out


def motor_torque(jf: np.ndarray, motor: int, masses_kg: np.ndarray, centers_home_m: np.ndarray,
                 gravity_world: np.ndarray = (0.0, 0.0, -9.81),
                 T_world_base: np.ndarray | None = None, samples: int = SAMPLES, *,  # noqa: N803
                 length_unit_m: float = 1.0, theta: np.ndarray | None = None,
                 resting_link: int = 0) -> MotorTorque:
    """Quasi-static motor torque (N m) against gravity, ``dU/dtheta = -sum_l m_l g_rest .
    dc_l/dtheta`` (virtual work) with ``resting_link`` held still (velocities relative to it,
    in its frame); link masses ``(6,)``, centres ``(6, 3)`` (m, base frame, home);
    ``T_world_base`` 4x4 or dual quaternion (8,): the resting link's home frame in the world,
    None = identity; ``length_unit_m``: metres per length unit of ``jf``. At
    :func:`motor_angles` or ``theta``; see docs/realization.md."""
    _, a, b = norm_roots(jf)
    m, unit = check_index("motor", motor, 0, 5), check_positive("length_unit_m", length_unit_m)
    rest = check_index("resting_link", resting_link, 0, 5)
    mass = _array("masses_kg", masses_kg, (6,))
    if (mass < 0).any():
        raise ValueError("masses_kg must be >= 0")
    tf = np.eye(4) if T_world_base is None else np.asarray(T_world_base, dtype=np.float64)
    if tf.shape not in ((4, 4), (8,)) or not np.isfinite(tf).all():
        raise ValueError(f"T_world_base must be a finite 4x4 matrix or (8,), got {tf.shape}")
    r = tf[:3, :3] if tf.ndim == 2 else dq.rotation_matrix(tf) if tf[:4].any() else np.zeros((3, 3))
    if np.abs(r @ r.T - np.eye(3)).max() > TOL.orthonormal or np.linalg.det(r) < 0:
        raise ValueError("T_world_base must be a rigid motion (its rotation is not proper)")
    g_base = r.T @ _array("gravity_world", gravity_world, (3,))
    th = (motor_angles(a, b, m, check_index("samples", samples, 8, 10**7)) if theta is None
          else _array("theta", theta, None))
    t, g, _ = gear(a, b, m, th)
    poses = loops.link_poses(jf, t)
    c = dq.transform_points(poses,  # (T, 6, 3) in the units of jf
                            _array("centers_home_m", centers_home_m, (6, 3)) / unit)
    twist = np.einsum("lj,tj,tjk->tlk", _CHAIN, g, loops.axes_at(jf, t))
    twist = twist - twist[:, rest:rest + 1]  # relative to the resting link (base frame)
    dc = np.cross(twist[..., :3], c) + twist[..., 3:]  # point velocity per rad: w x c + v0
    # into the resting link's frame (its rotation over the cycle; gravity is fixed there)
    dc = np.einsum("tji,tlj->tli", dq.rotation_matrix(dq.normalize(poses[:, rest])), dc)
    torque = -unit * np.einsum("l,tlk,k->t", mass, dc, g_base)
    moving = float(mass.sum() - mass[rest])
    return MotorTorque(m, th, t, torque, float(np.abs(torque).max()), moving)
