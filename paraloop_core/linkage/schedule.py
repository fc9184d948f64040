"""Motor speed schedules (TOPP) of a loop with one joint as motor: joint speed and acceleration
limits met over the whole cycle in a given cycle time (docs/realization.md, Speed schedule).

Notation as :mod:`drive`: motor angle ``theta``, gear ratios ``g_j``, ``g_j'``; the schedule
is ``x = omega^2`` linear in theta within each step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from paraloop_core.errors import ParaloopError
from paraloop_core.linkage import drive

TWO_PI = drive.TWO_PI
_REFINE = 0.25  # schedule steps keep Delta |g'/g| <= this: TOPP's step maps stay increasing
_RTOL = 1e-9  # limits and cycle time hold to this (rounding of the final scaling)
_SWEEPS = 60  # periodic passes of the schedule recursions (2 sufficed in all tests)
#: The schedule bounds accelerations at 3 points per step with this margin; between them they
#: vary by O(step^2) (measured <= 8e-4 relative), and :data:`DENSE` points per step check it.
ACCEL_MARGIN = 0.01
DENSE = 33  #: points per schedule step where achieved accelerations are evaluated


class InfeasibleScheduleError(ParaloopError):
    """No motor profile meets the limits: ``min_cycle_time`` (s), ``accel_needed`` (rad/s^2 for
    the requested cycle time, same ratio), ``min_speed_ratio`` (needed to exceed); inf: none."""

    reason = "infeasible-schedule"

    def __init__(self, message: str, tmin: float, need: float, ratio: float):
        super().__init__(message)
        self.min_cycle_time, self.accel_needed, self.min_speed_ratio = tmin, need, ratio


@dataclass(frozen=True)
class SpeedSchedule:
    """See :func:`speed_schedule`; node arrays ``(N+1,)`` / ``(N+1, 6)``, theta 0 .. 2 pi."""

    motor: int
    cycle_time: float
    theta: np.ndarray  # rad; the last node closes the cycle
    t: np.ndarray
    time: np.ndarray  # s, 0 .. cycle_time
    motor_speed: np.ndarray  # rad/s > 0, last = first
    velocity: np.ndarray  # joint velocities, rad/s
    acceleration: np.ndarray  # rad/s^2 in the step starting at the node (last row = first)
    achieved_speed_ratio: np.ndarray  # (6,) max|v_j| / (2 pi / cycle_time)
    achieved_accel: np.ndarray  # (6,) max|a_j| at DENSE points per step
    fastest_cycle_time: float  # s, of the fastest admissible profile (then slowed down)


def schedule_grid(a: np.ndarray, b: np.ndarray, m: int, n: int) -> tuple[np.ndarray, ...]:
    """nodes ``(N+1,)``; g, g' ``(2N+1, 6)`` (nodes, midpoints); q/p, 1/p ``(N, 18)``; pair; t."""
    th = drive.motor_angles(a, b, m, n)
    for _ in range(60):  # halve steps until Delta |g'/g| <= _REFINE (g_j never vanishes)
        nodes = np.append(th, TWO_PI)
        k, mids = len(th), 0.5 * (nodes[:-1] + nodes[1:])
        t, g, gp = drive.gear(a, b, m, np.concatenate([nodes, mids]))
        rel = np.abs(gp / g).max(axis=1)
        bad = np.diff(nodes) * np.maximum.reduce([rel[:k], rel[1:k + 1], rel[k + 1:]]) > _REFINE
        if not bad.any():
            break
        th = np.sort(np.concatenate([th, mids[bad]]))
    # at x = (1 - lam) x_k + lam x_{k+1}, x' = (x_{k+1} - x_k) / Delta, the acceleration
    # g' x + g x'/2 is sign(g) (p x_{k+1} - q x_k) with p, q >= |g| / (4 Delta) > 0
    half = 0.5 / np.diff(nodes)[:, None, None]
    gg = np.stack([g[:k], g[k + 1:], g[1:k + 1]], axis=1)
    gq = np.stack([gp[:k], gp[k + 1:], gp[1:k + 1]], axis=1) * np.sign(gg)
    lam = np.array([0.0, 0.5, 1.0])[:, None]
    p = (np.abs(gg) * half + gq * lam).reshape(k, -1)
    sig = (np.abs(gg) * half - gq * (1.0 - lam)).reshape(k, -1) / p
    ds = sig[:, :, None] - sig[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):  # lo_i(x) <= hi_j(x) for all i, j
        pair = np.where(ds > 0, (1.0 / p[:, :, None] + 1.0 / p[:, None, :]) / ds, np.inf)
    return nodes, g, gp, sig, 1.0 / p, pair.min(axis=(1, 2)), t[: k + 1]


def speed_caps(g: np.ndarray, v: float) -> np.ndarray:
    """Caps on ``x = omega^2`` at nodes for joint speeds <= v (min over the neighbours)."""
    c = v * v / (g**2).max(axis=1)
    ext = np.concatenate([c[-2:-1], c[:-1], c[:2]])  # node N is node 0
    return np.minimum(np.minimum(ext[:-2], ext[1:-1]), ext[2:])


def step_times(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    return 2.0 * np.diff(nodes) / (np.sqrt(x[:-1]) + np.sqrt(x[1:]))  # exact, x linear per step


def fastest(gr: tuple[np.ndarray, ...], cap: np.ndarray, accel: float
             ) -> tuple[np.ndarray, float]:
    """Fastest admissible periodic ``x = omega^2`` ``(N+1,)`` and its time (s)."""
    sig, eps = gr[3], accel * gr[4]
    inv_s, eo, bound = 1.0 / sig, eps / sig, np.minimum(cap[:-1], accel * gr[5]).tolist()
    n = len(bound)
    beta, x = np.empty(n + 1), np.empty(n + 1)
    end = bound[0]
    for _ in range(_SWEEPS):  # scalar recursions: the one loop over samples
        beta[n] = bk = end
        for k in range(n - 1, -1, -1):
            bk = beta[k] = min(bound[k], float((bk * inv_s[k] + eo[k]).min()))
        if bk >= end * (1.0 - 1e-13):
            break
        end = bk
    beta[0] = beta[n] = start = min(beta[0], end)
    for _ in range(_SWEEPS):
        x[0] = xk = start
        for k in range(n):
            xk = x[k + 1] = min(beta[k + 1], float((sig[k] * xk + eps[k]).min()))
        if xk >= start * (1.0 - 1e-13):
            break
        start = xk
    x[n] = x[0]
    return x, float(step_times(gr[0], x).sum())


def speed_schedule(jf: np.ndarray, motor: int, cycle_time: float, max_speed_ratio: float,
                   max_accel: float, samples: int = drive.SAMPLES) -> SpeedSchedule:
    """Motor profile keeping every joint's speed <= ``max_speed_ratio * 2 pi / cycle_time`` and
    |acceleration| <= ``max_accel`` (rad/s^2), cycle time exactly ``cycle_time`` (s): TOPP in
    ``x = omega^2``, slowed down uniformly. Raises :class:`InfeasibleScheduleError`.

    Accelerations are bounded at 3 points per step, :data:`ACCEL_MARGIN` below ``max_accel``,
    then evaluated at :data:`DENSE` points per step; should they still exceed ``max_accel``
    the bound is lowered by the excess and the profile recomputed (the times and limits an
    error names are those of the bound used)."""
    _, a, b = drive.norm_roots(jf)
    m, ct = drive.check_index("motor", motor, 0, 5), drive.check_positive("cycle_time", cycle_time)
    ratio, user_acc = (drive.check_positive("max_speed_ratio", max_speed_ratio),
                       drive.check_positive("max_accel", max_accel))
    gr = schedule_grid(a, b, m, drive.check_index("samples", samples, 8, 10**7))
    nodes, g, gp, k = gr[0], gr[1], gr[2], len(gr[0])
    acc = user_acc * (1.0 - ACCEL_MARGIN)
    for _ in range(4):
        x, fast = fastest(gr, speed_caps(g[:k], ratio * TWO_PI / ct), acc)
        if fast > ct * (1.0 + 1e-12):
            _infeasible(gr, m, ct, ratio, user_acc, acc, fast)
        x = x * (fast / ct) ** 2
        got_acc = _dense_accel(a, b, m, nodes, x)
        if got_acc.max() <= user_acc * (1 + _RTOL):
            break
        acc *= user_acc / got_acc.max() * (1.0 - ACCEL_MARGIN)
    else:
        raise RuntimeError("speed schedule violates its acceleration limit (bug)")
    w, slope = np.sqrt(x), (0.5 * np.diff(x) / np.diff(nodes))[:, None]  # domega/dtime
    vel = g[:k] * w[:, None]
    got_ratio = np.abs(vel).max(0) / (TWO_PI / ct)
    if got_ratio.max() > ratio * (1 + _RTOL):
        raise RuntimeError("speed schedule violates its speed limit (bug)")
    return SpeedSchedule(m, ct, nodes, gr[6],
                         np.concatenate([[0.0], np.cumsum(step_times(nodes, x))]), w, vel,
                         np.concatenate([gp[:k - 1] * x[:-1, None] + g[:k - 1] * slope,
                                         gp[:1] * x[:1, None] + g[:1] * slope[:1]]),
                         got_ratio, got_acc, fast)


def _infeasible(gr: tuple[np.ndarray, ...], m: int, ct: float, ratio: float, user_acc: float,
                acc: float, fast: float) -> None:
    """Raise :class:`InfeasibleScheduleError` for limits ``ratio``, ``user_acc`` (applied as
    the bound ``acc``) whose fastest profile takes ``fast`` > ``ct`` s, naming what works."""
    # caps scale with the mean speed, so T with accel A is the T = 1 problem with accel A T^2,
    # fastest time decreasing in it: log bisection
    nodes, g, k = gr[0], gr[1], len(gr[0])
    head = (f"no motor-{m} speed schedule meets max_speed_ratio {ratio:g} and max_accel "
            f"{user_acc:g} rad/s^2 in {ct:g} s (the fastest admissible profile takes "
            f"{fast:.6g} s)")
    cap1 = speed_caps(g[:k], ratio * TWO_PI)
    at_cap = float(step_times(nodes, cap1).sum())  # time with unlimited acceleration
    if at_cap >= 1.0 - 1e-9:
        raise InfeasibleScheduleError(
            f"{head}; no cycle time works: max_speed_ratio must exceed {ratio * at_cap:.6g}"
            " (the cycle mean of the largest joint gear ratio)", np.inf, np.inf, ratio * at_cap)
    lo = hi = acc * ct * ct
    while fastest(gr, cap1, hi)[1] > 1.0:
        lo, hi = hi, 4.0 * hi
    while hi > lo * (1.0 + 1e-9):
        mid = float(np.sqrt(lo * hi))
        lo, hi = (mid, hi) if fastest(gr, cap1, mid)[1] > 1.0 else (lo, mid)
    tmin = float(np.sqrt(hi / acc)) * (1 + 1e-9)
    need = hi / ct**2 * (user_acc / acc) * (1 + 1e-9)
    raise InfeasibleScheduleError(
        f"{head}; the smallest cycle time that works for these limits is {tmin:.9g} s; for "
        f"{ct:g} s use max_accel >= {need:.6g} rad/s^2, or max_speed_ratio "
        f"{ratio * fast / ct:.6g} with max_accel {user_acc * (fast / ct) ** 2:.6g} rad/s^2",
        tmin, need, ratio * at_cap)


def _dense_accel(a: np.ndarray, b: np.ndarray, m: int, nodes: np.ndarray, x: np.ndarray
                 ) -> np.ndarray:
    """``max |g_j' x + g_j x'/2|`` ``(6,)`` at :data:`DENSE` points per step (x linear)."""
    lam = np.linspace(0.0, 1.0, DENSE)
    delta = np.diff(nodes)
    _, g, gp = drive.gear(a, b, m, (nodes[:-1, None] + delta[:, None] * lam).ravel())
    xs = (x[:-1, None] * (1.0 - lam) + x[1:, None] * lam).ravel()[:, None]
    slope = np.repeat(0.5 * np.diff(x) / delta, DENSE)[:, None]
    return np.abs(gp * xs + g * slope).max(axis=0)
