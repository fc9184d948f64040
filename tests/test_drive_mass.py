"""Motor torque of the printed parts' masses (:mod:`fabrication.drive_mass`): the slope of the
built parts' potential energy, the report's entry, the line for people."""

from __future__ import annotations

import fab_fixtures as F
import numpy as np
import pytest

from paraloop_core.algebra import dq
from paraloop_core.design import DriveSettings
from paraloop_core.fabrication import base, choice, drive_mass, profiles, stiffness
from paraloop_core.linkage import drive, loops


@pytest.mark.parametrize(("resting", "motor", "standing"), [(None, None, True), (3, 4, False)])
def test_torque_is_the_slope_of_the_parts_potential_energy(resting, motor, standing):
    """Independent check of frames and masses: each built part's mesh (and each piece of
    hardware) is moved by its link's pose relative to the resting link (mm), its centre of
    mass taken there; the potential energy ``g sum m (up . x)``, differenced in the motor
    angle, equals the torque from the link masses."""
    pr = F.printed()
    asm = pr.assembly
    resting = pr.base.link if resting is None else resting
    motor = drive.recommend_motor(asm.joint_factors, resting).motor if motor is None else motor
    up = pr.base.up if standing else np.array([0.0, 0.0, 1.0])
    rho = F.PLA.density_g_cm3
    mass, centers = base.link_masses(asm, rho)
    theta = np.linspace(0.3, 2 * np.pi - 0.3, 9)
    tq = drive_mass.gravity_torque(asm.joint_factors, asm.scale, mass, centers, resting, motor,
                                   theta, up).torque
    solids = [(F.mesh_of(p.manifold), p.link, rho) for p in asm.parts]
    solids += [(F.mesh_of(h.solid), h.link, profiles.STEEL_G_CM3) for h in asm.hardware]
    a, b = asm.joint_factors[motor, 0], np.linalg.norm(asm.joint_factors[motor, 1:4])

    def energy(th: np.ndarray) -> np.ndarray:  # J, at motor angles th
        poses = dq.to_matrix(loops.link_poses(asm.joint_factors, a - b / np.tan(th / 2)))
        poses[..., :3, 3] *= asm.scale  # mm
        rel = np.linalg.inv(poses[:, resting, None]) @ poses
        e = np.zeros(len(th))
        for tm, link, density in solids:
            x = rel[:, link, :3, :3] @ tm.center_mass + rel[:, link, :3, 3]
            e += 9.81 * tm.volume * density * 1e-6 * (x @ up) * 1e-3  # kg, m
        return e

    step = 1e-4
    fd = (energy(theta + step) - energy(theta - step)) / (2 * step)
    assert np.abs(tq).max() > 1e-3  # a real torque, not zeros
    assert tq == pytest.approx(fd, abs=1e-5 * np.abs(fd).max())


def test_the_report_entry_and_its_settings():
    pr = F.printed()
    asm, g = pr.assembly, pr.base.link
    d = pr.report["drive"]
    assert d["resting_link"] == g and d["motor_chosen"] == "recommended"
    assert d["motor"] == drive.recommend_motor(asm.joint_factors, g).motor
    assert d["density_kg_m3"] == pytest.approx(1240.0) and d["material"] == "PLA"
    masses, _ = base.link_masses(asm, F.PLA.density_g_cm3)
    assert d["link_masses_kg"] == pytest.approx(masses * 1e-3, rel=1e-5)
    assert d["moving_mass_kg"] == pytest.approx(sum(d["link_masses_kg"])
                                                - d["link_masses_kg"][g], rel=1e-5)
    assert len(d["torque_n_m"]) == len(d["theta_rad"]) == drive_mass.CURVE_SAMPLES
    assert d["peak_torque_n_m"] >= np.abs(d["torque_n_m"]).max() * (1 - 1e-5)
    assert np.ptp(d["torque_n_m"]) > 0
    assert d["gravity_home_m_s2"] == pytest.approx(-9.81 * pr.base.up)
    assert d["worst_speed_ratio"] == pytest.approx(
        drive.smooth_drive_penalty(asm.joint_factors, d["motor"]))
    assert d["worst_speed_ratio"] < drive.HOLD_RATIO  # a smooth loop: no warning
    assert not any("no motor holds" in w for w in pr.report["warnings"])
    # the design's motor is used as given; twice the masses, twice the torque
    masses, centers = base.link_masses(asm, F.PLA.density_g_cm3)
    args = (asm.joint_factors, asm.scale)
    one = drive_mass.entry(*args, masses, centers, g, DriveSettings(motor=5), F.PLA,
                           pr.base.up)
    two = drive_mass.entry(*args, 2 * masses, centers, g, DriveSettings(motor=5), F.PLA,
                           pr.base.up)
    assert one["motor"] == 5 and one["motor_chosen"] == "design"
    assert two["peak_torque_n_m"] == pytest.approx(2 * one["peak_torque_n_m"], rel=1e-9)
    assert two["moving_mass_kg"] == pytest.approx(2 * one["moving_mass_kg"], rel=1e-9)


def test_drive_line_says_why_when_the_torque_is_missing():
    assert drive_mass.drive_line({"error": "part x is not a closed solid: no mass"}) == \
        "motor torque not computed: part x is not a closed solid: no mass"
    assert drive_mass.material(1240) == "PLA 1240 kg/m^3"
    assert drive_mass.material(1000.0) == "density 1000 kg/m^3"
    entry = F.printed().report["drive"]
    line = drive_mass.drive_line(entry)
    assert "N*m" in line and "PLA 1240 kg/m^3" in line and "resting link" in line
    # past the ratio no motor holds the loop: no torque, the hand
    fast = {**entry, "worst_speed_ratio": 2 * drive_mass.drive.HOLD_RATIO}
    line = drive_mass.drive_line(fast)
    assert "N*m" not in line and "by hand" in line and "PLA 1240 kg/m^3" in line
    # the guide's summary says the same: a motor where one holds the loop, else the hand
    from paraloop_core.fabrication import guide, profiles

    pr = F.printed()
    for entry_, says, never in ((entry, "Motor (optional)", "by hand"),
                                (fast, "Drive: by hand", "Motor")):
        report = {**pr.report, "parts": [{"mass_g": 5.0}], "drive": entry_,
                  "choice": {**pr.report["choice"], "note": "the design's loop"}}
        text = " ".join(guide.guide_text(pr.assembly, report, profiles.MATERIALS["pla"],
                                         {})["summary"])
        assert says in text and never not in text


def test_a_loop_one_motor_cannot_hold_is_named(monkeypatch):
    """Past :data:`drive.HOLD_RATIO` the export warns that a motor cannot hold the loop and
    says what would work (here the limit lowered under the fixture's smooth loop)."""
    from paraloop_core.fabrication import printable

    monkeypatch.setattr(drive_mass.drive, "HOLD_RATIO", 1.0)
    cand = choice.Candidate("test loop", 4, lambda: (F.real(), None))
    pr = printable.make([cand], printable.Options(size_mm=F.SIZE_MM, samples=16,
                                                  ground=False))
    ratio = pr.report["drive"]["worst_speed_ratio"]
    warning = next(w for w in pr.report["warnings"] if "no motor holds" in w)
    assert f"{ratio:.0f} times slower" in warning and "smooth-drive" in warning


def test_gap_closed_names_the_pair_furthest_under_three_deflections():
    pairs = [{"links": [0, 1], "adjacent": True, "continuous_min_gap_mm": 0.1},
             {"links": [0, 2], "adjacent": False, "continuous_min_gap_mm": 7.0},
             {"links": [1, 3], "adjacent": False, "continuous_min_gap_mm": 5.0}]
    total = np.array([1.0, 0.5, 1.0, 1.0, 0.0, 0.0])
    # 0-2 needs 3 x 2 = 6 mm (kept), 1-3 needs 4.5 mm (kept); adjacent pairs never count
    assert stiffness.gap_closed(total, pairs) is None
    closed = stiffness.gap_closed(2 * total, pairs)  # 12 mm and 9 mm needed
    assert closed == {"links": [0, 2], "deflection_mm": [2.0, 2.0], "gap_mm": 7.0,
                      "required_gap_mm": 12.0}
    entry = {"worst_speed_ratio": 2.0, "peak_torque_n_m": 0.5, "motor": 3,
             "motor_bends": closed, "moving_mass_kg": 0.1, "density_kg_m3": 1240.0}
    assert drive_mass.by_hand(entry) and "bend links 0 and 2 by 2.0 and 2.0 mm" in \
        drive_mass.hand_reason(entry) and "by hand" in drive_mass.drive_line(entry)
    assert not drive_mass.by_hand({**entry, "motor_bends": None})


def test_a_motor_that_would_bend_links_shut_is_not_used(monkeypatch):
    """A motor 1000 times stronger than the loop needs (a stiff joint, a stiff gear): its
    peak torque would bend two links without a common joint into each other; the export
    turns the loop by hand, says why, and its deflections (self-weight only) keep every
    verified gap."""
    from paraloop_core.fabrication import printable

    cand = choice.Candidate("test loop", 4, lambda: (F.real(), None))
    opts = printable.Options(size_mm=F.SIZE_MM, samples=16, ground=False)
    stiff = printable.make([cand], opts).report
    assert "motor_bends" not in stiff["drive"]
    assert stiff["stiffness"]["links"][0]["torque_deflection_mm"] is not None
    entry = drive_mass.entry
    monkeypatch.setattr(drive_mass, "entry", lambda *a, **k: {
        **entry(*a, **k), "peak_torque_n_m": 1e3 * stiff["drive"]["peak_torque_n_m"]})
    report = printable.make([cand], opts).report
    bent = report["drive"]["motor_bends"]
    assert bent["required_gap_mm"] > bent["gap_mm"]
    assert drive_mass.by_hand(report["drive"])
    assert all(s["torque_deflection_mm"] is None for s in report["stiffness"]["links"])
    assert any(f"bend links {bent['links'][0]} and {bent['links'][1]}" in w
               for w in report["warnings"])
    sag = {s["link"]: s["sag_mm"] for s in report["stiffness"]["links"]}
    for p in report["verification"]["pairs"]:
        a, b = p["links"]
        assert p["adjacent"] or p["continuous_min_gap_mm"] >= 3 * (sag[a] + sag[b])


def test_the_motor_moves_to_a_joint_whose_torque_keeps_the_gaps(monkeypatch):
    """Only the recommended joint's torque would bend links shut: the motor moves to the
    smoothest other joint that holds the loop, the report, the warning and the drive the
    animation and the physics check use (:func:`printed.drive_of`) say so."""
    from paraloop_core import printed as printed_mod
    from paraloop_core.design import DriveSettings
    from paraloop_core.fabrication import printable

    cand = choice.Candidate("test loop", 4, lambda: (F.real(), None))
    opts = printable.Options(size_mm=F.SIZE_MM, samples=16, ground=False)
    first = printable.make([cand], opts).report["drive"]
    entry = drive_mass.entry

    def strong_first(*a, **k):
        e = entry(*a, **k)
        return {**e, "peak_torque_n_m": e["peak_torque_n_m"] * (
            1e3 if e["motor"] == first["motor"] else 1.0)}

    monkeypatch.setattr(drive_mass, "entry", strong_first)
    pr = printable.make([cand], opts)
    d = pr.report["drive"]
    assert d["motor_chosen"] == printable.MOTOR_KEEPS_GAPS and d["motor"] != first["motor"]
    assert d["motor_bends_at"]["motor"] == first["motor"] and not drive_mass.by_hand(d)
    assert pr.report["stiffness"]["motor_torque_nm"] == pytest.approx(d["peak_torque_n_m"])
    assert any(f"the motor is on joint {d['motor']}" in w for w in pr.report["warnings"])
    assert printed_mod.drive_of(pr, DriveSettings()).motor == d["motor"]
    assert printed_mod.drive_of(pr, DriveSettings(motor=None)).cycle_time_s == 10.0


def test_a_near_singular_loop_is_turned_by_hand():
    """A printed loop near a singular pose (its candidate says so): no motor (one on a
    joint can let it switch branches), the loop is turned by hand and the warning says why;
    a motor the design fixes is kept."""
    from paraloop_core.fabrication import printable

    cand = choice.Candidate("near loop", 4, lambda: (F.real(), None), near_singular=True)
    opts = printable.Options(size_mm=F.SIZE_MM, samples=16, ground=False)
    rep = printable.make([cand], opts).report
    assert rep["drive"]["near_singular"] and drive_mass.by_hand(rep["drive"])
    assert rep["stiffness"]["motor_torque_nm"] is None
    assert any("switch to another branch" in w and "by hand" in w for w in rep["warnings"])
    assert not any("smooth-drive" in w for w in rep["warnings"])  # a smooth loop
    assert sum("singular configuration" in w for w in rep["warnings"]) == 1
    fixed = printable.make([cand], opts, DriveSettings(motor=2)).report
    assert "near_singular" not in fixed["drive"] and fixed["drive"]["motor"] == 2
    assert any("design's motor on joint 2 can let it switch" in w for w in fixed["warnings"])
