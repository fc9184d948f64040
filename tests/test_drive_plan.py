"""Drive plan: motor, chosen or user limits, schedule or infeasibility message, JSON form."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from paraloop_core import design, pipeline
from paraloop_core.design import DriveSettings
from paraloop_core.linkage import drive, drive_plan, schedule
from tests.test_drive import BUNDLED, DESIGNS, bundled, generic

RTOL = 1e-9  # speed_schedule holds its limits to this
RANDOM_SEEDS = (0, 3, 16, 28)  # worst constant-speed ratios 15 .. 1e9


def _meets_limits(plan: drive_plan.DrivePlan) -> None:
    s = plan.schedule
    assert s is not None and plan.error is None
    assert s.achieved_speed_ratio.max() <= plan.max_speed_ratio * (1 + RTOL)
    assert s.achieved_accel.max() <= plan.max_accel_rad_s2 * (1 + RTOL)
    assert s.cycle_time == plan.cycle_time_s and s.motor == plan.motor


def _least_ratio(jf: np.ndarray, motor: int) -> float:
    """R0: the ratio no acceleration can beat (named by the infeasibility error)."""
    with pytest.raises(schedule.InfeasibleScheduleError) as info:
        schedule.speed_schedule(jf, motor, 10.0, 1.0, 1.0)
    return info.value.min_speed_ratio


@pytest.mark.parametrize("name", BUNDLED)
def test_default_limits_give_a_schedule_for_the_bundled_examples(name):
    d = design.load_design(DESIGNS / f"{name}.json")
    assert d.drive == DriveSettings()  # no drive section: the defaults
    plan = drive_plan.plan_drive(bundled(name), d.drive)
    _meets_limits(plan)
    assert plan.cycle_time_s == 10.0
    assert (plan.speed_ratio_chosen_by, plan.accel_chosen_by) == ("program", "program")
    r0, worst = _least_ratio(bundled(name), plan.motor), plan.constant.peak_speed_ratio.max()
    # the rule: max(1.05 R0, min(sqrt(W R0), 2 R0)) on the coarse grid (R0 1-3 % above), rounded up
    assert 1.05 * r0 <= plan.max_speed_ratio <= 1.05 * max(math.sqrt(worst * r0), 1.05 * r0)
    assert plan.max_speed_ratio < 0.8 * worst  # a clear improvement over constant speed
    # the acceleration limit is 1.25 x the least that works: the profile comes close to it
    assert 0.7 <= plan.schedule.achieved_accel.max() / plan.max_accel_rad_s2 <= 1.0
    for limit in (plan.max_speed_ratio, plan.max_accel_rad_s2):  # 3 significant digits
        assert float(f"{limit:.3g}") == limit


@pytest.mark.parametrize("seed", RANDOM_SEEDS)
def test_default_limits_work_for_loops_with_very_fast_turns(seed):
    plan = drive_plan.plan_drive(generic(seed), DriveSettings(cycle_time_s=3.0))
    _meets_limits(plan)
    r0 = _least_ratio(generic(seed), plan.motor)
    assert plan.max_speed_ratio <= 2.0 * 1.1 * r0  # near R0 even when W is 1e9 (coarse R0)


def test_user_limits_are_used_and_respected():
    jf = bundled("tv8")
    plan = drive_plan.plan_drive(jf, DriveSettings(max_speed_ratio=2.5, max_accel_rad_s2=1.0))
    _meets_limits(plan)
    assert (plan.max_speed_ratio, plan.max_accel_rad_s2) == (2.5, 1.0)
    assert (plan.speed_ratio_chosen_by, plan.accel_chosen_by) == ("user", "user")
    only_ratio = drive_plan.plan_drive(jf, DriveSettings(max_speed_ratio=1.5))
    _meets_limits(only_ratio)
    assert only_ratio.max_speed_ratio == 1.5 and only_ratio.accel_chosen_by == "program"
    only_accel = drive_plan.plan_drive(jf, DriveSettings(max_accel_rad_s2=0.1, cycle_time_s=20))
    _meets_limits(only_accel)
    assert only_accel.max_accel_rad_s2 == 0.1 and only_accel.speed_ratio_chosen_by == "program"
    # the least acceleration any profile needs in 10 s is 0.2 rad/s^2 (the default ratio
    # needs no more): just above it works, below it no ratio does
    tight = drive_plan.plan_drive(jf, DriveSettings(max_accel_rad_s2=0.21))
    _meets_limits(tight)
    low = drive_plan.plan_drive(jf, DriveSettings(max_accel_rad_s2=0.19))
    assert low.schedule is None and "for 10 s use max_accel >= 0.2" in low.error


def test_least_ratio_and_accel_are_bracketed():
    coarse = drive_plan._Coarse(bundled("tv8"), 0)
    r0 = coarse.min_ratio
    floor = coarse.least_accel(1e3)  # ~20.2 (cycle time 1): what any profile needs
    need = coarse.least_accel(1.1 * r0)  # the speed cap binds: more is needed
    assert need > 1.05 * floor and coarse.time(1.1 * r0, need) <= 1.0
    assert coarse.time(1.1 * r0, need / 1.02) > 1.0
    assert coarse.least_accel(r0) == np.inf
    ratio = coarse.least_ratio(need, 1.01 * r0)  # the accel that 1.1 r0 needs: ~1.1 r0
    assert coarse.time(ratio, need) <= 1.0 < coarse.time(ratio / 1.02, need)
    assert 1.07 * r0 < ratio <= 1.1 * r0 * 1.02
    assert coarse.least_ratio(need, 2.0 * r0) == 2.0 * r0  # feasible start: kept
    assert coarse.least_ratio(0.95 * floor, 2.0 * r0) == np.inf  # below any profile's need


@pytest.mark.parametrize("limits, words", [
    ({"max_speed_ratio": 1.0}, "max_speed_ratio must exceed"),
    ({"max_speed_ratio": 1.0, "max_accel_rad_s2": 5.0}, "no cycle time works"),
    ({"max_speed_ratio": 2.5, "max_accel_rad_s2": 0.01}, "smallest cycle time that works"),
])
def test_infeasible_user_limits_give_the_message_not_an_exception(limits, words):
    plan = drive_plan.plan_drive(bundled("tv8"), DriveSettings(**limits))
    assert plan.schedule is None and words in plan.error
    out = drive_plan.plan_to_dict(plan)
    assert out["schedule"] == {"error": plan.error}
    json.dumps(out, allow_nan=False)
    if "max_accel_rad_s2" not in limits:  # no acceleration makes ratio 1 feasible
        assert plan.max_accel_rad_s2 is None and "with any acceleration" in plan.error


def test_motor_recommended_or_user():
    jf = bundled("arc-sculpture")
    rec = drive.recommend_motor(jf, 0)
    plan = drive_plan.plan_drive(jf, DriveSettings())
    assert (plan.motor, plan.motor_reason, plan.motor_chosen_by) == (rec.motor, rec.reason,
                                                                     "program")
    other = (rec.motor + 2) % 6
    mine = drive_plan.plan_drive(jf, DriveSettings(motor=other))
    assert (mine.motor, mine.motor_chosen_by, mine.schedule.motor) == (other, "user", other)
    assert mine.motor_reason.startswith(f"joint {other}: set in the design")
    assert "recommended: " + rec.reason in mine.motor_reason
    np.testing.assert_array_equal(mine.peak_speed_ratios, rec.peak_speed_ratio)
    rest2 = drive_plan.plan_drive(jf, DriveSettings(), resting_link=2)
    assert rest2.motor == drive.recommend_motor(jf, 2).motor and rest2.resting_link == 2


def test_plan_to_dict_is_strict_compact_json_and_torque_iff_masses():
    jf = bundled("tv8")
    out = drive_plan.plan_to_dict(drive_plan.plan_drive(jf, DriveSettings(motor=1)))
    text = json.dumps(out, allow_nan=False)
    assert len(text) < 6000 and "torque" not in out
    assert out["motor"] == 1 and out["motor_chosen_by"] == "user"
    assert out["limits"]["chosen_by"] == {"max_speed_ratio": "program",
                                          "max_accel_rad_s2": "program"}
    prof = out["schedule"]["profile"]
    assert len(prof["time_s"]) == len(prof["motor_speed_rad_s"]) == 65
    assert prof["time_s"][0] == 0.0 and prof["time_s"][-1] == 10.0
    assert prof["motor_angle_rad"][0] == 0.0 and prof["motor_angle_rad"][-1] == 2 * np.pi
    assert all(v > 0 for v in prof["motor_speed_rad_s"])
    assert len(out["constant_speed"]["worst_speed_ratio_by_motor"]) == 6
    rng = np.random.default_rng(1)
    masses, centers = rng.uniform(0.01, 0.1, 6), rng.normal(size=(6, 3)) * 0.05
    plan = drive_plan.plan_drive(jf, DriveSettings(motor=1, density_kg_m3=1000.0),
                                 masses_kg=masses, centers_home_m=centers, length_unit_m=0.01)
    torque = drive.motor_torque(jf, 1, masses, centers, length_unit_m=0.01)
    out = drive_plan.plan_to_dict(plan)
    json.dumps(out, allow_nan=False)
    assert out["torque"] == {"peak_torque_n_m": torque.peak_torque,
                             "moving_mass_kg": torque.moving_mass_kg, "density_kg_m3": 1000.0}
    with pytest.raises(ValueError, match="both masses_kg and centers_home_m"):
        drive_plan.plan_drive(jf, DriveSettings(), masses_kg=masses)


@pytest.mark.parametrize("kwargs, words", [
    ({"settings": None}, "fields of design.DriveSettings"),
    ({"settings": DriveSettings(motor=6)}, "motor must be an integer in 0..5"),
    ({"settings": DriveSettings(cycle_time_s=0.0)}, "cycle_time_s must be a positive"),
    ({"settings": DriveSettings(max_speed_ratio=0.5)}, "max_speed_ratio must be >= 1"),
    ({"settings": DriveSettings(max_accel_rad_s2=float("nan"))}, "max_accel_rad_s2"),
    ({"resting_link": 7}, "resting_link"),
    ({"joint_factors": np.zeros((6, 8))}, "no rotation axis"),
])
def test_invalid_input_raises_value_error(kwargs, words):
    args = {"joint_factors": bundled("tv8"), "settings": DriveSettings(), **kwargs}
    with pytest.raises(ValueError, match=words):
        drive_plan.plan_drive(**args)


def test_fastest_time_falls_at_most_like_accel_to_the_minus_half():
    """The bound the limit search relies on: T*(A / c) <= sqrt(c) T*(A) for c > 1."""
    for jf in (bundled("tv8"), generic(3)):
        coarse = drive_plan._Coarse(jf, 0)
        for ratio in (1.2 * coarse.min_ratio, 3.0 * coarse.min_ratio):
            for acc in (1.0, 30.0, 1e3, 1e5):
                for c in (1.1, 4.0, 100.0):
                    assert coarse.time(ratio, acc / c) <= math.sqrt(c) * coarse.time(
                        ratio, acc) * (1 + 1e-9)


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.sampled_from(("tv8", *RANDOM_SEEDS)), motor=st.none() | st.integers(0, 5),
       cycle=st.floats(0.01, 1e6), ratio=st.none() | st.floats(1.0, 20.0),
       accel=st.none() | st.floats(-6, 9).map(lambda e: 10.0**e))
def test_achieved_never_exceeds_the_limits(seed, motor, cycle, ratio, accel):
    jf = bundled(seed) if isinstance(seed, str) else generic(seed)
    plan = drive_plan.plan_drive(jf, DriveSettings(motor, cycle, ratio, accel))
    json.dumps(drive_plan.plan_to_dict(plan), allow_nan=False)
    if ratio is None and accel is None:
        _meets_limits(plan)  # chosen limits always work
    if plan.schedule is not None:
        _meets_limits(plan)
        assert ratio in (None, plan.max_speed_ratio) and accel in (None, plan.max_accel_rad_s2)
    else:
        assert plan.error.startswith("no motor-") and (ratio, accel) != (None, None)


def test_result_json_has_the_drive_section_and_never_fails_on_it():
    d = design.load_design(DESIGNS / "tv8.json")
    sol = pipeline.solve(replace(d, drive=DriveSettings(motor=1, cycle_time_s=5.0)),
                         realize=False)
    out = pipeline.result_to_dict(sol)["drive"]
    assert out == drive_plan.plan_to_dict(drive_plan.plan_drive(
        sol.loop.joint_factors, sol.design.drive))
    assert out["motor"] == 1 and out["cycle_time_s"] == 5.0 and "achieved_speed_ratio" in \
        out["schedule"]
    bad = replace(sol, design=replace(sol.design, drive=DriveSettings(cycle_time_s=-1.0)))
    assert pipeline.result_to_dict(bad)["drive"] == {
        "error": "cycle_time_s must be a positive finite number, got -1.0"}


def test_result_json_has_the_drive_plan_when_asked():
    """Designs whose drive settings are the defaults get no drive plan unless asked (it costs
    about twice the rest of the solve); ``drive=True`` adds it, ``drive=False`` drops it."""
    d = design.load_design(DESIGNS / "tv8.json")
    assert d.drive == DriveSettings()
    sol = pipeline.solve(d, realize=False)
    assert "drive" not in pipeline.result_to_dict(sol)
    full = pipeline.result_to_dict(sol, drive=True)["drive"]
    assert full == drive_plan.plan_to_dict(drive_plan.plan_drive(sol.loop.joint_factors,
                                                                 DriveSettings()))
    asked = replace(sol, design=replace(d, drive=DriveSettings(cycle_time_s=10.5)))
    assert "drive" in pipeline.result_to_dict(asked)
    assert "drive" not in pipeline.result_to_dict(asked, drive=False)
