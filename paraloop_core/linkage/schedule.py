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
_POLICY = 12  # piece choices tried per pass before the scalar recursion (2 - 4 suffice)
_DEFECT = 1e-11  # summed relative defects accepted: y within 1e-11 of the exact recursion
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


@dataclass(frozen=True)
class Grid:
    """The schedule grid of one motor: ``nodes`` ``(N+1,)`` (0 .. 2 pi), ``t`` ``(N+1,)``;
    ``g``, ``gp`` ``(2N+1, 6)`` at the nodes then the step midpoints. Step k's acceleration
    at ``lam`` in (0, 1/2, 1) of joint j is ``sign(g) (p x_{k+1} - q x_k)`` (18 pieces i =
    (lam, j)): ``sig`` = q/p, ``inv_p`` = 1/p, ``inv_q`` = 1/q ``(18, N)``; ``pair`` ``(N,)``
    the largest ``x_k`` with an admissible next step per unit acceleration."""

    nodes: np.ndarray
    t: np.ndarray
    g: np.ndarray
    gp: np.ndarray
    sig: np.ndarray
    inv_p: np.ndarray
    inv_q: np.ndarray
    pair: np.ndarray


def schedule_grid(a: np.ndarray, b: np.ndarray, m: int, n: int) -> Grid:
    """The :class:`Grid` of motor m: :func:`drive.motor_angles` (``n`` per family), steps
    halved until ``Delta |g'/g| <= _REFINE`` at their ends and midpoint (g_j never vanishes)."""
    nodes = np.append(drive.motor_angles(a, b, m, n), TWO_PI)
    mids = 0.5 * (nodes[:-1] + nodes[1:])
    (tn, gn, gpn), (tm, gm, gpm) = drive.gear(a, b, m, nodes), drive.gear(a, b, m, mids)
    for _ in range(60):
        rn, rm = np.abs(gpn / gn).max(axis=1), np.abs(gpm / gm).max(axis=1)
        bad = np.diff(nodes) * np.maximum(np.maximum(rn[:-1], rn[1:]), rm) > _REFINE
        if not bad.any():
            break
        # split the bad steps at their midpoints: only the new midpoints need the gear
        k = np.flatnonzero(bad)
        left, right = 0.5 * (nodes[k] + mids[k]), 0.5 * (mids[k] + nodes[k + 1])
        tl, gl, gpl = drive.gear(a, b, m, left)
        tr, gr, gpr = drive.gear(a, b, m, right)
        nodes, tn = np.insert(nodes, k + 1, mids[k]), np.insert(tn, k + 1, tm[k])
        gn, gpn = np.insert(gn, k + 1, gm[k], axis=0), np.insert(gpn, k + 1, gpm[k], axis=0)
        mids, tm = np.insert(mids, k + 1, right), np.insert(tm, k + 1, tr)
        gm, gpm = np.insert(gm, k + 1, gr, axis=0), np.insert(gpm, k + 1, gpr, axis=0)
        j = k + np.arange(len(k))  # where the split steps' left halves now are
        mids[j], tm[j], gm[j], gpm[j] = left, tl, gl, gpl
    # at x = (1 - lam) x_k + lam x_{k+1}, x' = (x_{k+1} - x_k) / Delta, the acceleration
    # g' x + g x'/2 is sign(g) (p x_{k+1} - q x_k) with p, q >= |g| / (4 Delta) > 0
    half = 0.5 / np.diff(nodes)
    gg = np.stack([gn[:-1], gm, gn[1:]])  # (3 lam, N, 6)
    gq = np.stack([gpn[:-1], gpm, gpn[1:]]) * np.sign(gg)
    lam = np.array([0.0, 0.5, 1.0])[:, None, None]
    ag = np.abs(gg) * half[:, None]
    p = np.moveaxis(ag + gq * lam, 1, 2).reshape(18, -1)  # (18 = lam x joint, N)
    q = np.moveaxis(ag - gq * (1.0 - lam), 1, 2).reshape(18, -1)
    return Grid(nodes, tn, np.concatenate([gn, gm]), np.concatenate([gpn, gpm]), q / p,
                1.0 / p, 1.0 / q, _pair(q / p, 1.0 / p))


def _pair(sig: np.ndarray, inv_p: np.ndarray) -> np.ndarray:
    """``min (w_i + w_j) / (sig_i - sig_j)`` over pieces with ``sig_i > sig_j`` ``(N,)``, inf
    if none (``sig``, ``w = inv_p`` ``(18, N)``): the largest x_k whose next step can meet
    both the lower bounds ``sig_i x - w_i`` and the upper bounds ``sig_j x + w_j``, i.e. the
    root of the concave ``min_j (sig_j x + w_j) - max_i (sig_i x - w_i)``. Newton's method
    from the right (from a pair's crossing, which is >= the root) takes the active pair's
    crossing each time and stops at the root after a few steps: no 18 x 18 pairs."""
    cols = np.arange(sig.shape[1])
    hi, lo = np.argmax(sig, axis=0), np.argmin(sig, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(sig[hi, cols] > sig[lo, cols], (inv_p[hi, cols] + inv_p[lo, cols])
                     / (sig[hi, cols] - sig[lo, cols]), np.inf)
    live = np.flatnonzero(np.isfinite(x))
    for _ in range(4 * len(sig)):
        if not live.size:
            return x
        s, w, xl = sig[:, live], inv_p[:, live], x[live]
        i, j = np.argmax(s * xl - w, axis=0), np.argmin(s * xl + w, axis=0)
        c = np.arange(live.size)
        with np.errstate(divide="ignore", invalid="ignore"):
            new = (w[i, c] + w[j, c]) / (s[i, c] - s[j, c])
        moved = (s[i, c] > s[j, c]) & (new < xl)
        x[live[moved]] = new[moved]
        live = live[moved]
    raise RuntimeError("schedule grid: pair bound did not converge (bug)")


def speed_caps(g: np.ndarray, v: float) -> np.ndarray:
    """Caps on ``x = omega^2`` at nodes for joint speeds <= v (min over the neighbours)."""
    c = v * v / (g**2).max(axis=1)
    ext = np.concatenate([c[-2:-1], c[:-1], c[:2]])  # node N is node 0
    return np.minimum(np.minimum(ext[:-2], ext[1:-1]), ext[2:])


def step_times(nodes: np.ndarray, x: np.ndarray) -> np.ndarray:
    return 2.0 * np.diff(nodes) / (np.sqrt(x[:-1]) + np.sqrt(x[1:]))  # exact, x linear per step


def _one_piece(cap: np.ndarray, a: np.ndarray, c: np.ndarray, y_end: float) -> np.ndarray:
    """``y`` ``(n+1,)``: ``y_n = y_end``, ``y_k = min(cap_k, a_k y_{k+1} + c_k)`` (a, c > 0).
    With ``Q_k = prod_{l>=k} a_l`` and ``D_k = sum_{l>=k} c_l / Q_l`` the recursion is a
    running minimum: ``y_k / Q_k - D_k = min(cap_k / Q_k - D_k, y_{k+1} / Q_{k+1} - D_{k+1})``.
    """
    q = np.cumprod(a[::-1])[::-1]
    d = np.cumsum((c / q)[::-1])[::-1]
    w = np.minimum.accumulate(np.append(cap / q - d, y_end)[::-1])[::-1]
    return np.append(q * (w[:-1] + d), y_end)


def _chain(cap: np.ndarray, a: np.ndarray, c: np.ndarray, y_end: float,
           piece: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``y`` ``(n+1,)`` of the TOPP recursion ``y_n = y_end``, ``y_k = min(cap_k, min_i (a_ik
    y_{k+1} + c_ik))`` (pieces ``a``, ``c`` ``(P, n)`` > 0), and the active piece per step.

    Policy iteration: solve with one piece per step (:func:`_one_piece`), re-pick each
    step's smallest piece at the solution, until the summed relative defects of the full
    recursion are <= :data:`_DEFECT` (each piece is increasing, so the error of y relative
    to the exact recursion is at most that sum). Otherwise the scalar recursion."""
    n, idx = len(cap), np.arange(len(cap))
    with np.errstate(all="ignore"):
        if piece is None:
            piece = np.argmin(a * np.append(cap[1:], y_end) + c, axis=0)
        for _ in range(_POLICY):
            y = _one_piece(cap, a[piece, idx], c[piece, idx], y_end)
            vals = a * y[1:] + c
            new = np.argmin(vals, axis=0)
            f = np.minimum(cap, vals[new, idx])
            if np.sum(np.abs(f - y[:-1]) / y[:-1]) <= _DEFECT:
                return y, new
            if np.array_equal(new, piece):  # rounding, not the pieces: no better this way
                break
            piece = new
    y = np.empty(n + 1)
    y[n] = yk = y_end
    for k in range(n - 1, -1, -1):  # the scalar recursion (rarely needed)
        yk = y[k] = min(cap[k], float((a[:, k] * yk + c[:, k]).min()))
    return y, piece


def fastest(gr: Grid, cap: np.ndarray, accel: float) -> tuple[np.ndarray, float]:
    """Fastest admissible periodic ``x = omega^2`` ``(N+1,)`` and its time (s): the greatest
    profile under the caps whose decelerations (backward pass) and accelerations (forward
    pass) stay within ``accel``, each pass repeated round the cycle until it closes."""
    bound = np.minimum(cap[:-1], accel * gr.pair)
    n, piece = len(bound), None
    back_a, back_c = 1.0 / gr.sig, accel * gr.inv_q
    end = bound[0]
    for _ in range(_SWEEPS):
        beta, piece = _chain(bound, back_a, back_c, end, piece)
        if beta[0] >= end * (1.0 - 1e-13):
            break
        end = beta[0]
    beta[0] = beta[n] = start = min(beta[0], end)
    # forward: x_{k+1} = min(beta_{k+1}, min_i (sig_ik x_k + accel / p_ik)), steps reversed
    fwd_a, fwd_c, piece = gr.sig[:, ::-1], accel * gr.inv_p[:, ::-1], None
    for _ in range(_SWEEPS):
        z, piece = _chain(beta[:0:-1], fwd_a, fwd_c, start, piece)
        if z[0] >= start * (1.0 - 1e-13):
            break
        start = z[0]
    x = z[::-1].copy()
    x[n] = x[0]
    return x, float(step_times(gr.nodes, x).sum())


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
    nodes, g, gp, k = gr.nodes, gr.g, gr.gp, len(gr.nodes)
    acc = user_acc * (1.0 - ACCEL_MARGIN)
    for _ in range(4):
        x, fast = fastest(gr, speed_caps(g[:k], ratio * TWO_PI / ct), acc)
        if fast > ct * (1.0 + 1e-12):
            _infeasible(gr, m, ct, ratio, user_acc, acc, fast)
        x = x * (fast / ct) ** 2
        got_acc = _dense_accel(a, b, m, gr, x)
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
    return SpeedSchedule(m, ct, nodes, gr.t,
                         np.concatenate([[0.0], np.cumsum(step_times(nodes, x))]), w, vel,
                         np.concatenate([gp[:k - 1] * x[:-1, None] + g[:k - 1] * slope,
                                         gp[:1] * x[:1, None] + g[:1] * slope[:1]]),
                         got_ratio, got_acc, fast)


def _infeasible(gr: Grid, m: int, ct: float, ratio: float, user_acc: float,
                acc: float, fast: float) -> None:
    """Raise :class:`InfeasibleScheduleError` for limits ``ratio``, ``user_acc`` (applied as
    the bound ``acc``) whose fastest profile takes ``fast`` > ``ct`` s, naming what works."""
    # caps scale with the mean speed, so T with accel A is the T = 1 problem with accel A T^2,
    # fastest time decreasing in it: log bisection
    nodes, g, k = gr.nodes, gr.g, len(gr.nodes)
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


def _dense_accel(a: np.ndarray, b: np.ndarray, m: int, gr: Grid, x: np.ndarray) -> np.ndarray:
    """``max |g_j' x + g_j x'/2|`` ``(6,)`` at :data:`DENSE` points per step (x linear).

    Each ``g_j``, ``g_j'`` is monotone within a step (:func:`drive.motor_angles`), so
    ``max|g'| max x + max|g| |x'/2|`` over the step's ends bounds it there: only steps whose
    bound exceeds a joint's maximum at the nodes and midpoints are sampled densely."""
    nodes, k, g, gp = gr.nodes, len(gr.nodes), gr.g, gr.gp
    delta = np.diff(nodes)
    slope = (0.5 * np.diff(x) / delta)[:, None]
    xm = 0.5 * (x[:-1] + x[1:])
    at = np.abs(np.concatenate([gp[:k - 1] * x[:-1, None] + g[:k - 1] * slope,
                                gp[k:] * xm[:, None] + g[k:] * slope,
                                gp[1:k] * x[1:, None] + g[1:k] * slope]))
    best = at.max(axis=0)  # (6,) at the 3 points of every step (all among the dense points)
    ag, agp = np.abs(g[:k]), np.abs(gp[:k])
    bound = (np.maximum(agp[:-1], agp[1:]) * np.maximum(x[:-1], x[1:])[:, None]
             + np.maximum(ag[:-1], ag[1:]) * np.abs(slope))
    steps = np.flatnonzero((bound > best * (1.0 - 1e-9)).any(axis=1))
    lam = np.linspace(0.0, 1.0, DENSE)
    _, gd, gpd = drive.gear_rows(a, b, m, (nodes[steps, None] + delta[steps, None] * lam).ravel())
    gpd *= (x[steps, None] * (1.0 - lam) + x[steps + 1, None] * lam).ravel()
    gd *= np.repeat(slope[steps, 0], DENSE)
    gpd += gd
    return np.maximum(best, np.abs(gpd).max(axis=1, initial=0.0))
