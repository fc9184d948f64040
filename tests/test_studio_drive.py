"""Headless tests of the studio's Drive folder: plots after a full update, the motor control,
an infeasible limit's message, the settings through Save / Load, the parts' torque."""

from __future__ import annotations

import json

import numpy as np
import pytest
import test_studio_fabrication
from test_studio_server import click, gizmo, settle, upload

from app.panels.drive import NO_PARTS, checked, parse_limit
from paraloop_core import design as design_mod
from paraloop_core.design import DriveSettings

tv8 = test_studio_fabrication.tv8  # the fixture: the tv8 example in a headless studio
TWO_PI = 2.0 * np.pi


def drawn(app) -> None:
    """The worker idle and the Drive folder's plan drawn."""
    settle(app)
    assert app.drive.wait_idle(30)


def test_plots_get_data_after_a_full_update(tv8):
    drawn(tv8)
    d, plan = tv8.drive, tv8.drive.plan
    assert plan is not None and plan.motor_chosen_by == "program" and plan.resting_link == 0
    assert d.ms and "Motor: joint" in d.summary.content and "chosen by the program" in \
        d.summary.content
    ct = tv8.state.design.drive.cycle_time_s
    limit = plan.max_speed_ratio * TWO_PI / ct
    t, *speeds, line = d.constant.data
    assert len(t) > 100 and t[0] == 0.0 and t[-1] == pytest.approx(ct)
    assert np.all(np.diff(t) > 0) and np.allclose(line, limit)
    assert np.allclose(speeds[plan.motor], TWO_PI / ct)  # the motor turns uniformly
    assert max(s.max() for s in speeds) > limit  # why a schedule is needed
    assert d.scheduled.visible
    t, *speeds, line = d.scheduled.data
    assert t[-1] == pytest.approx(ct) and np.allclose(line, limit)
    assert max(s.max() for s in speeds) <= limit * (1 + 1e-9)
    assert not d.torque.visible and d.torque_text.content == NO_PARTS


def test_plans_for_full_updates_only(tv8):
    drawn(tv8)
    n, plan = len(tv8.drive.ms), tv8.drive.plan
    p = tv8.state.design.poses[3].position + 0.01
    gizmo(tv8, 3, position=p, phases=("start", "update"))  # a drag preview
    drawn(tv8)
    assert len(tv8.drive.ms) == n and tv8.drive.plan is plan
    gizmo(tv8, 3, position=p, phases=("end",))  # released: a full update
    drawn(tv8)
    assert len(tv8.drive.ms) == n + 1  # the moved loop's accelerations
    assert not np.allclose(tv8.drive.plan.constant.peak_accel, plan.constant.peak_accel,
                           rtol=1e-9, atol=0.0)


def test_motor_control_edits_the_design_and_the_plot(tv8):
    drawn(tv8)
    recommended = tv8.drive.plan.motor
    worst = tv8.drive.plan.peak_speed_ratios.max(axis=1)  # by motor
    other = int(np.argmin(worst))  # joint 1 of tv8: smoother, but not on the grounded link
    assert other != recommended and worst[other] < worst[recommended]
    tv8.drive.inputs["motor"].value = f"joint {other}"
    drawn(tv8)
    assert tv8.state.design.drive.motor == other and tv8.drive.plan.motor == other
    assert f"motor joint {other}" in tv8.drive.constant.title
    speeds = tv8.drive.constant.data[1:7]
    assert np.allclose(speeds[other], TWO_PI / tv8.state.design.drive.cycle_time_s)
    assert not np.allclose(speeds[recommended], speeds[recommended][0])
    tv8.drive.inputs["motor"].value = "Recommended"
    drawn(tv8)
    assert tv8.state.design.drive.motor is None and tv8.drive.plan.motor == recommended


def test_infeasible_speed_ratio_shows_the_planners_message(tv8):
    tv8.drive.inputs["max_speed_ratio"].value = "1.01"
    drawn(tv8)
    d = tv8.drive
    assert tv8.state.design.drive.max_speed_ratio == 1.01 and d.plan.schedule is None
    assert "none meets these limits" in d.summary.content
    assert "max_speed_ratio must exceed" in d.summary.content  # what would work
    assert not d.scheduled.visible and not any(err for _, _, err in tv8.notifications)
    d.inputs["max_speed_ratio"].value = "fast"  # not a number: refused, written back
    assert tv8.notifications[-1][2] and "not a number" in tv8.notifications[-1][1]
    d.inputs["max_accel_rad_s2"].value = "-2"  # out of range: refused, design kept
    assert "drive.max_accel_rad_s2" in tv8.notifications[-1][1]
    drawn(tv8)
    assert d.inputs["max_speed_ratio"].value == "1.01" and d.inputs["max_accel_rad_s2"].value == ""
    assert tv8.state.design.drive == DriveSettings(max_speed_ratio=1.01)
    d.inputs["max_speed_ratio"].value = ""  # back to automatic: feasible again
    drawn(tv8)
    assert tv8.state.design.drive.max_speed_ratio is None and d.scheduled.visible


def test_settings_survive_save_and_load(tv8):
    d = tv8.drive.inputs
    d["motor"].value = "joint 1"
    d["cycle_time_s"].value = 20.0
    d["max_speed_ratio"].value = "2.5"
    d["max_accel_rad_s2"].value = "0.3"
    d["density_kg_m3"].value = 1000.0
    want = DriveSettings(1, 20.0, 2.5, 0.3, 1000.0)
    assert tv8.state.design.drive == want
    click(tv8.panels.save)
    saved = tv8.downloads[-1][1]
    assert design_mod.design_from_dict(json.loads(saved)).drive == want
    original = design_mod.design_to_dict(design_mod.load_design(
        test_studio_fabrication.DESIGNS / "tv8.json"))
    upload(tv8, "tv8.json", json.dumps(original).encode())
    assert d["motor"].value == "Recommended" and d["max_speed_ratio"].value == ""
    upload(tv8, "saved.json", saved)
    drawn(tv8)
    assert tv8.state.design.drive == want and tv8.drive.plan.motor == 1
    assert (d["motor"].value, d["cycle_time_s"].value, d["max_speed_ratio"].value,
            d["max_accel_rad_s2"].value, d["density_kg_m3"].value) == (
        "joint 1", 20.0, "2.5", "0.3", 1000.0)
    assert tv8.drive.constant.data[0][-1] == pytest.approx(20.0)


def test_torque_of_the_fabricated_parts_until_the_design_changes(tv8):
    """A finished export's report (its ``drive`` entry, as ``drive_mass.entry`` writes
    it) gives the torque curve; a design change that moves the bars makes it stale."""
    drawn(tv8)
    theta = np.arange(128) * (TWO_PI / 128)
    entry = {"motor": tv8.drive.plan.motor, "resting_link": 0, "density_kg_m3": 1240.0,
             "link_masses_kg": [0.02, 0.017, 0.017, 0.017, 0.017, 0.016],
             "moving_mass_kg": 0.084, "peak_torque_n_m": 0.05, "theta_rad": theta.tolist(),
             "torque_n_m": (0.05 * np.sin(theta)).tolist()}
    tv8.fabrication.report_for = tv8.solution.realization  # what the export job records
    tv8.fabrication.report = {"drive": entry}
    tv8._busy(None)  # what the end of the export job does
    drawn(tv8)
    d = tv8.drive
    assert d.torque.visible and "0.084 kg moving, PLA" in d.torque_text.content
    x, y = d.torque.data
    assert x[0] == 0.0 and x[-1] == 360.0 and y[-1] == y[0] and len(x) == 129
    assert "Export all again" not in d.torque_text.content
    d.inputs["density_kg_m3"].value = 1000.0  # the parts were exported at 1240
    drawn(tv8)
    assert d.torque.visible and "Export all again" in d.torque_text.content
    gizmo(tv8, 3, position=tv8.state.design.poses[3].position + 0.01)
    drawn(tv8)
    assert not d.torque.visible and d.torque_text.content == NO_PARTS
    # an export of another realization (e.g. an edit landed before it ended): not shown
    tv8.fabrication.report_for = None
    tv8.fabrication.report = {"drive": entry}
    tv8._busy(None)
    drawn(tv8)
    assert not d.torque.visible and d.torque_text.content == NO_PARTS
    # a torque the export could not compute says why
    tv8.fabrication.report_for = tv8.solution.realization
    tv8.fabrication.report = {"drive": {"error": "link_2 is not a closed solid: no mass"}}
    tv8._busy(None)
    drawn(tv8)
    assert not d.torque.visible and "not a closed solid" in d.torque_text.content


def test_parse_limit_and_checked_settings():
    assert parse_limit("  ") is None and parse_limit("Auto") is None
    assert parse_limit(" 2.5 ") == 2.5
    with pytest.raises(ValueError, match="not a number"):
        parse_limit("2,5")
    design = design_mod.load_design(test_studio_fabrication.DESIGNS / "tv8.json")
    assert checked(design, "max_speed_ratio", 3.0).drive.max_speed_ratio == 3.0
    for key, bad in (("max_speed_ratio", 0.5), ("cycle_time_s", 0.0), ("motor", 6),
                     ("density_kg_m3", float("nan"))):
        with pytest.raises(ValueError, match=f"drive.{key}"):
            checked(design, key, bad)


def test_a_drive_edit_keeps_the_solution_and_the_fabrication(tv8):
    """The drive settings change no motion, loop or realization: the cached solution is kept
    (so carved and exported parts stay current), only the plan is redrawn."""
    real = tv8.solution.realization
    tv8.drive.inputs["cycle_time_s"].value = 20.0
    settle(tv8)
    assert tv8.drive.wait_idle(30)
    assert tv8.state.design.drive.cycle_time_s == 20.0
    assert tv8.solution.realization is real
    assert tv8.drive.plan.cycle_time_s == 20.0
