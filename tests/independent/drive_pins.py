"""Pinned drive-plan values (``tests/data/drive_pins.json``): the numbers of the scalar TOPP
implementation (Python loops over the grid, commit a381d0a, with the BLAS-independent
critical-point finder of ``drive._accel_critical`` and the 2 pi duplicate dropped), which the
array version must reproduce to 1e-9 relative. Regenerate only on purpose: ``.venv/bin/python
-m tests.independent.drive_pins`` (it overwrites the file with the current code's numbers).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from paraloop_core import design, pipeline
from paraloop_core.design import DriveSettings
from paraloop_core.linkage import drive, drive_plan, schedule

from .generic_designs import random_design

PINS = Path(__file__).resolve().parents[1] / "data" / "drive_pins.json"
DESIGNS = Path(__file__).resolve().parents[2] / "assets" / "designs"
BUNDLED = ("arc-sculpture", "shading-panel", "sun-disc", "sun-path-fit", "tv8")
SEEDS = (0, 3, 7, 16, 25, 28, 41, 57)
#: settings per case: defaults, a user motor, user ratio, user accel, both (feasible or not)
SETTINGS = (
    {},
    {"motor": 2, "cycle_time_s": 3.0},
    {"max_speed_ratio": 3.0},
    {"max_accel_rad_s2": 0.5, "cycle_time_s": 20.0},
    {"max_speed_ratio": 2.5, "max_accel_rad_s2": 0.01},
    {"max_speed_ratio": 1.0},
)
STRIDE = 101  # every STRIDE-th schedule node is pinned (with the node count and sums)
#: Accelerations are slopes of x = omega^2 over a step: over steps narrower than this (rad;
#: grids have steps down to 1e-12 rad where samples nearly coincide) the rounding of x
#: (1e-16 relative) becomes 1e-4 of them in any implementation. ``achieved_accel_wide``
#: is their maximum over the wider steps only, well conditioned.
WIDE = 1e-6


def loops_of(name: str | int) -> list[np.ndarray]:
    """Joint factors ``(6, 8)`` of every generic loop of a bundled design or random seed."""
    d = (design.load_design(DESIGNS / f"{name}.json") if isinstance(name, str)
         else design.design_from_dict(random_design(name)))
    sol = pipeline.solve(d, realize=False)
    return [lp.joint_factors for lp in sol.loops]


def cases() -> list[tuple[str | int, int, dict]]:
    """(design, loop index, settings): every bundled design's loop 0 with all settings and
    loop 4 with the first four, and loop (seed mod 9) of each random seed with the defaults
    and a user motor."""
    out = [(n, k, s) for n in BUNDLED for k in (0, 4) for s in SETTINGS[:6 if k == 0 else 4]]
    return out + [(s, s % 9, st) for s in SEEDS for st in SETTINGS[:2]]


def _arr(x: np.ndarray) -> list:
    return np.asarray(x, dtype=np.float64).tolist()


def accel_wide(jf: np.ndarray, s: schedule.SpeedSchedule) -> np.ndarray:
    """``max |g' x + g x'/2|`` ``(6,)`` at ``schedule.DENSE`` points of every step wider than
    :data:`WIDE` of a schedule (x linear per step)."""
    _, a, b = drive.norm_roots(jf)
    x, delta = s.motor_speed**2, np.diff(s.theta)
    k = np.flatnonzero(delta > WIDE)
    lam = np.linspace(0.0, 1.0, schedule.DENSE)
    _, g, gp = drive.gear(a, b, s.motor, (s.theta[k, None] + delta[k, None] * lam).ravel())
    xs = (x[k, None] * (1.0 - lam) + x[k + 1, None] * lam).ravel()[:, None]
    slope = np.repeat(0.5 * (x[k + 1] - x[k]) / delta[k], schedule.DENSE)[:, None]
    return np.abs(gp * xs + g * slope).max(axis=0)


def schedule_pins(jf: np.ndarray, s: schedule.SpeedSchedule) -> dict:
    """Node count, every STRIDE-th node and the sums of each node array of a schedule."""
    arrays = {"theta": s.theta, "t": s.t, "time": s.time, "motor_speed": s.motor_speed,
              "velocity": s.velocity, "acceleration": s.acceleration}
    out = {"nodes": len(s.theta), "achieved_speed_ratio": _arr(s.achieved_speed_ratio),
           "achieved_accel": _arr(s.achieved_accel), "fastest": s.fastest_cycle_time,
           "achieved_accel_wide": _arr(accel_wide(jf, s))}
    for key, x in arrays.items():
        fin = np.where(np.isfinite(x), x, 0.0)
        out[key] = _arr(fin[::STRIDE if fin.ndim == 1 else 3 * STRIDE])
        out[key + "_abs_sum"] = float(np.abs(fin).sum())
    return out


def pin(name: str | int, loop: int, settings: dict, jf: np.ndarray | None = None) -> dict:
    """The pinned numbers of one case (``jf`` ``(6, 8)``: its loop; None = solved here). The
    pins keep each loop's joint factors: solves differ in their last bits between machines
    (BLAS kernels), the drive plan is pinned for the same input."""
    jf = loops_of(name)[loop] if jf is None else jf
    plan = drive_plan.plan_drive(jf, DriveSettings(**settings))
    out = {"design": name, "loop": loop, "settings": settings, "joint_factors": _arr(jf),
           "plan": drive_plan.plan_to_dict(plan)}
    if plan.schedule is not None:
        out["schedule"] = schedule_pins(jf, plan.schedule)
    _, a, b = drive.norm_roots(jf)
    coarse = drive_plan._Coarse(jf, plan.motor)
    # 1 / pair: the pair bound (w_i + w_j) / (sig_i - sig_j) is ill-conditioned where it is
    # huge (sig_i ~ sig_j) and then never binds; its inverse is well conditioned
    out["coarse"] = {"nodes": len(coarse.grid.nodes), "min_ratio": coarse.min_ratio,
                     "inv_pair_sum": float(np.sum(1.0 / coarse.grid.pair)),
                     "least_accel": [coarse.least_accel(f * coarse.min_ratio)
                                     for f in (1.05, 1.5, 4.0)],
                     "time": [coarse.time(f * coarse.min_ratio, acc)
                              for f in (1.05, 2.0) for acc in (0.3, 30.0, 3e3)]}
    out["dense_grid_nodes"] = len(schedule.schedule_grid(a, b, plan.motor, drive.SAMPLES).nodes)
    try:  # a tight schedule: infeasible for most loops, naming the least cycle time
        schedule.speed_schedule(jf, plan.motor, 1.0, 1.5 * coarse.min_ratio, 1.0)
        out["tight"] = None
    except schedule.InfeasibleScheduleError as exc:
        out["tight"] = [exc.min_cycle_time, exc.accel_needed, exc.min_speed_ratio]
    return out


def _round(x):
    """Floats to 12 significant digits (the pins hold to 1e-9): a smaller file."""
    if isinstance(x, float):
        return float(f"{x:.12g}")
    if isinstance(x, dict):
        return {k: v if k == "joint_factors" else _round(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_round(v) for v in x]
    return x


def main() -> None:
    PINS.parent.mkdir(exist_ok=True)
    data = _round([pin(*c) for c in cases()])
    PINS.write_text(json.dumps(data, allow_nan=True) + "\n")
    print(f"wrote {len(data)} cases to {PINS}")


if __name__ == "__main__":
    main()


def scalar_fastest(gr: schedule.Grid, cap: np.ndarray, accel: float) -> tuple[np.ndarray, float]:
    """:func:`schedule.fastest` as the scalar loops over the steps it replaced (a reference)."""
    sig, eps = gr.sig.T, accel * gr.inv_p.T
    inv_s, eo = 1.0 / sig, eps / sig
    bound = np.minimum(cap[:-1], accel * gr.pair)
    n = len(bound)
    beta, x = np.empty(n + 1), np.empty(n + 1)
    end = bound[0]
    for _ in range(60):
        beta[n] = bk = end
        for k in range(n - 1, -1, -1):
            bk = beta[k] = min(bound[k], float((bk * inv_s[k] + eo[k]).min()))
        if bk >= end * (1.0 - 1e-13):
            break
        end = bk
    beta[0] = beta[n] = start = min(beta[0], end)
    for _ in range(60):
        x[0] = xk = start
        for k in range(n):
            xk = x[k + 1] = min(beta[k + 1], float((sig[k] * xk + eps[k]).min()))
        if xk >= start * (1.0 - 1e-13):
            break
        start = xk
    x[n] = x[0]
    return x, float(schedule.step_times(gr.nodes, x).sum())
