"""Drive plan of a loop: motor joint, constant-speed peaks, schedule limits, schedule, torque.

Builds on :mod:`drive` (see docs/realization.md, Drive analysis). Limits the design leaves
null are chosen here so that a schedule exists for every loop: ``max_speed_ratio`` between
the least feasible ratio ``R0`` (the cycle mean of the largest gear ratio) and the
constant-speed worst ratio ``W``, ``max_accel`` a margin above the least acceleration that
makes it feasible in the cycle time. Infeasible limits of the design give a plan with the
reason (and what would work) instead of a schedule; no exception.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from paraloop_core.linkage import drive, schedule

TWO_PI = drive.TWO_PI
SEARCH_SAMPLES = 32  #: samples per family of the coarse grid the chosen limits are searched on
#: chosen max_speed_ratio = max(RATIO_MARGIN R0, min(sqrt(W R0), RATIO_SPAN R0))
RATIO_MARGIN, RATIO_SPAN = 1.05, 2.0
ACCEL_MARGIN = 1.25  #: chosen max_accel = this x the least feasible acceleration
PROFILE_NODES = 65  #: samples of the motor profile in :func:`plan_to_dict`
_BRACKET = 1.02  # least feasible values are bracketed to this factor
_DIGITS = 3  # chosen limits are rounded up to this many significant digits


class DriveSettingsLike(Protocol):
    """The fields of ``design.DriveSettings`` (not imported: design is above this layer)."""

    motor: int | None
    cycle_time_s: float
    max_speed_ratio: float | None
    max_accel_rad_s2: float | None
    density_kg_m3: float


@dataclass(frozen=True)
class DrivePlan:
    """See :func:`plan_drive`; ``*_chosen_by`` are ``"user"`` (the design) or ``"program"``."""

    motor: int
    motor_reason: str
    motor_chosen_by: str
    resting_link: int
    cycle_time_s: float
    peak_speed_ratios: np.ndarray  # (6 motors, 6 joints) at constant motor speed
    constant: drive.ConstantSpeed  # the motor at constant speed 2 pi / cycle_time_s
    max_speed_ratio: float  # the limits used
    max_accel_rad_s2: float | None  # None (chosen): no acceleration makes the ratio work
    speed_ratio_chosen_by: str
    accel_chosen_by: str
    schedule: schedule.SpeedSchedule | None  # None when infeasible (see error)
    error: str | None  # why there is no schedule and what would work
    torque: drive.MotorTorque | None  # when masses are given
    density_kg_m3: float


def _ceil(x: float) -> float:
    """``x > 0`` rounded up to :data:`_DIGITS` significant digits."""
    scale = 10.0 ** (math.floor(math.log10(x)) - _DIGITS + 1)
    return float(f"{math.ceil(x / scale) * scale:.{_DIGITS}g}")


class _Coarse:
    """The cycle-time-1 schedule problem of motor m on a coarse grid (``SEARCH_SAMPLES``):
    speed caps scale with the mean speed, so cycle time T with accel A is this with A T^2."""

    def __init__(self, jf: np.ndarray, m: int):
        _, a, b = drive.norm_roots(jf)
        self.grid = schedule.schedule_grid(a, b, m, SEARCH_SAMPLES)
        self.g = self.grid.g[: len(self.grid.nodes)]
        caps = schedule.speed_caps(self.g, TWO_PI)
        self.min_ratio = float(schedule.step_times(self.grid.nodes, caps).sum())

    def time(self, ratio: float, accel: float) -> float:
        """Fastest admissible cycle time."""
        return schedule.fastest(self.grid, schedule.speed_caps(self.g, ratio * TWO_PI), accel)[1]

    def least_accel(self, ratio: float) -> float:
        """An acceleration within ``_BRACKET`` above the least that makes ``ratio`` feasible
        (inf if none does). Fastest times fall at most like ``accel^-1/2`` (``x / c`` is
        admissible for ``accel / c``), so an accel A with time f bounds the least by A f^2:
        from below if f > 1, from above if f <= 1."""
        if ratio <= self.min_ratio * (1.0 + 1e-9):
            return np.inf
        lo, hi, acc = 0.0, np.inf, 1.0
        for _ in range(100):
            f = self.time(ratio, acc)
            if f > 1.0:
                lo = max(lo, acc * f * f)
            else:
                hi = min(hi, acc * f * f)
            if hi <= lo * _BRACKET:
                break
            acc = 4.0 * lo if hi == np.inf else hi / 4.0 if lo == 0.0 else math.sqrt(lo * hi)
        return hi

    def least_ratio(self, accel: float, start: float) -> float:
        """``start`` if feasible with ``accel``, else a ratio within ``_BRACKET`` above the
        least feasible one (times only fall as the ratio grows); inf if none up to 1e12 (the
        acceleration is below the least any motor profile needs in the cycle time)."""
        if self.time(start, accel) <= 1.0:
            return start
        if self.time(1e12, accel) > 1.0:
            return np.inf
        lo, hi = start, 4.0 * start
        while self.time(hi, accel) > 1.0:
            lo, hi = hi, 4.0 * hi
        while hi > lo * _BRACKET:
            mid = math.sqrt(lo * hi)
            lo, hi = (mid, hi) if self.time(mid, accel) > 1.0 else (lo, mid)
        return hi


def _check(settings: DriveSettingsLike) -> tuple[int | None, float, Any, Any, float]:
    names = ("motor", "cycle_time_s", "max_speed_ratio", "max_accel_rad_s2", "density_kg_m3")
    if not all(hasattr(settings, n) for n in names):
        raise ValueError(f"settings must have the fields of design.DriveSettings, got "
                         f"{type(settings).__name__}")
    motor = settings.motor
    ct = drive.check_positive("cycle_time_s", settings.cycle_time_s)
    ratio, acc = settings.max_speed_ratio, settings.max_accel_rad_s2
    if motor is not None:
        drive.check_index("motor", motor, 0, 5)
    if ratio is not None and drive.check_positive("max_speed_ratio", ratio) < 1.0:
        raise ValueError(f"max_speed_ratio must be >= 1 (or None), got {ratio!r}")
    if acc is not None:
        drive.check_positive("max_accel_rad_s2", acc)
    return motor, ct, ratio, acc, drive.check_positive("density_kg_m3", settings.density_kg_m3)


def plan_drive(joint_factors: np.ndarray, settings: DriveSettingsLike, resting_link: int = 0,
               *, masses_kg: np.ndarray | None = None, centers_home_m: np.ndarray | None = None,
               length_unit_m: float | None = None, T_world_base: np.ndarray | None = None,  # noqa: N803
               ) -> DrivePlan:
    """The drive of a loop ``joint_factors`` ``(6, 8)`` with ``settings`` (a
    ``design.DriveSettings``) and ``resting_link`` grounded: the motor (the settings', else
    :func:`drive.recommend_motor`), its constant-speed peaks, the schedule limits (null ones
    chosen, see the module doc) and :func:`schedule.speed_schedule`, or the reason it is
    infeasible; :func:`drive.motor_torque` when ``masses_kg`` ``(6,)`` and ``centers_home_m``
    ``(6, 3)`` are given (``length_unit_m``: metres per unit of the factors, None = 1).
    Raises ValueError only for invalid input."""
    jf = drive.norm_roots(joint_factors)[0]
    rest = drive.check_index("resting_link", resting_link, 0, 5)
    motor, ct, ratio, acc, density = _check(settings)
    if (masses_kg is None) != (centers_home_m is None):
        raise ValueError("give both masses_kg and centers_home_m, or neither")
    choice = drive.recommend_motor(jf, rest)
    if motor is None:
        m, reason = choice.motor, choice.reason
    else:
        m = motor
        reason = (f"joint {m}: set in the design (worst peak speed ratio "
                  f"{choice.peak_speed_ratio[m].max():.3g}); recommended: {choice.reason}")
    constant = drive.constant_speed(jf, m, ct)
    user, retry_ratio = (ratio is not None, acc is not None), False
    if not all(user):
        coarse = _Coarse(jf, m)
        r0, worst = coarse.min_ratio, float(constant.peak_speed_ratio.max())
        rule = max(RATIO_MARGIN * r0, min(math.sqrt(worst * r0), RATIO_SPAN * r0))
    if ratio is None:
        found = rule if acc is None else coarse.least_ratio(acc * ct**2, rule)
        retry_ratio = bool(np.isfinite(found))  # else no ratio works with this accel
        ratio = _ceil(rule if found == rule or not retry_ratio else RATIO_MARGIN * found)
    if acc is None:
        need = coarse.least_accel(ratio)  # inf: start at the constant-speed peak
        acc = _ceil(ACCEL_MARGIN * need / ct**2 if np.isfinite(need) else
                    max(float(constant.peak_accel.max()), 1.0 / ct**2))
    schedule, ratio, acc, error = _schedule(jf, m, ct, ratio, acc, user, retry_ratio)
    torque = None
    if masses_kg is not None:
        torque = drive.motor_torque(
            jf, m, masses_kg, centers_home_m, T_world_base=T_world_base, resting_link=rest,
            length_unit_m=1.0 if length_unit_m is None else length_unit_m)
    by = ("program", "user")
    return DrivePlan(m, reason, by[motor is not None], rest, ct, choice.peak_speed_ratio,
                     constant, ratio, acc, by[user[0]], by[user[1]], schedule, error, torque,
                     density)


def _schedule(jf: np.ndarray, m: int, ct: float, ratio: float, acc: float,
              user: tuple[bool, bool], retry_ratio: bool
              ) -> tuple[schedule.SpeedSchedule | None, float, float | None, str | None]:
    """``(schedule, ratio, accel, error)``: :func:`schedule.speed_schedule`; chosen limits the
    full grid refuses (the coarse search is close, not exact) are raised to what it names."""
    error = ""
    for _ in range(4):
        try:
            return schedule.speed_schedule(jf, m, ct, ratio, acc), ratio, acc, None
        except schedule.InfeasibleScheduleError as exc:
            error = str(exc)
            if not np.isfinite(exc.min_cycle_time):  # no acceleration makes the ratio work
                if user[0] and user[1]:
                    break
                if user[0]:
                    return None, ratio, None, (
                        f"no motor-{m} speed schedule meets max_speed_ratio {ratio:g} with any "
                        f"acceleration: max_speed_ratio must exceed {exc.min_speed_ratio:.6g} "
                        "(the cycle mean of the largest joint gear ratio)")
                ratio = _ceil(RATIO_MARGIN * exc.min_speed_ratio)
            elif not user[1]:
                acc = _ceil(ACCEL_MARGIN * exc.accel_needed)
            elif retry_ratio:
                ratio = _ceil(1.5 * ratio)
            else:
                break
    return None, ratio, acc, error


def _floats(x: np.ndarray) -> list[float]:
    x = np.asarray(x, dtype=np.float64)
    if not np.isfinite(x).all():
        raise ValueError("drive plan has a non-finite number (bug)")
    return x.tolist()


def plan_to_dict(plan: DrivePlan) -> dict[str, Any]:
    """JSON-ready dict of a plan (units in the key names; docs/result-format.md, ``drive``)."""
    cs = plan.constant
    out: dict[str, Any] = {
        "motor": plan.motor,
        "motor_reason": plan.motor_reason,
        "motor_chosen_by": plan.motor_chosen_by,
        "resting_link": plan.resting_link,
        "cycle_time_s": plan.cycle_time_s,
        "constant_speed": {
            "peak_speed_ratio": _floats(cs.peak_speed_ratio),
            "peak_accel_rad_s2": _floats(cs.peak_accel),
            "worst_speed_ratio_by_motor": _floats(plan.peak_speed_ratios.max(axis=1)),
        },
        "limits": {
            "max_speed_ratio": plan.max_speed_ratio,
            "max_accel_rad_s2": plan.max_accel_rad_s2,
            "chosen_by": {"max_speed_ratio": plan.speed_ratio_chosen_by,
                          "max_accel_rad_s2": plan.accel_chosen_by},
        },
    }
    s = plan.schedule
    if s is None:
        out["schedule"] = {"error": plan.error}
    else:
        frac = np.linspace(0.0, 1.0, PROFILE_NODES)
        time, at = frac * s.cycle_time, frac * s.time[-1]  # s.time[-1] = cycle time to 1e-15
        out["schedule"] = {
            "achieved_speed_ratio": _floats(s.achieved_speed_ratio),
            "achieved_accel_rad_s2": _floats(s.achieved_accel),
            "fastest_cycle_time_s": s.fastest_cycle_time,
            "profile": {"time_s": _floats(time),
                        "motor_angle_rad": _floats(np.interp(at, s.time, s.theta)),
                        "motor_speed_rad_s": _floats(np.interp(at, s.time, s.motor_speed))},
        }
    if plan.torque is not None:
        out["torque"] = {"peak_torque_n_m": plan.torque.peak_torque,
                         "moving_mass_kg": plan.torque.moving_mass_kg,
                         "density_kg_m3": plan.density_kg_m3}
    return out
