"""Link masses of the printed parts and the motor torque under gravity (drive_mass)."""

from __future__ import annotations

import argparse
import json

import manifold3d as m3d
import numpy as np
import pytest
from test_parts import example_assembly

from paraloop_core.algebra import dq
from paraloop_core.design import DriveSettings
from paraloop_core.fabrication import drive_mass, export, parts
from paraloop_core.linkage import drive, loops


def _part(link: int, solid: m3d.Manifold, name: str) -> parts.Part:
    return parts.Part(name, link, solid, np.zeros((1, 2, 3)), np.ones(1), np.full(1, -1))


def test_masses_of_known_solids():
    """A 10 x 20 x 30 mm box and a 12-gon prism on link 2, a cube on link 4: masses are
    density * volume, centres the mass-weighted centroids, in kg and m."""
    box = m3d.Manifold.cube([10.0, 20.0, 30.0]).translate([1.0, 2.0, 3.0])
    n, r, h = 12, 5.0, 8.0
    prism = m3d.Manifold.cylinder(h, r, r, n).translate([40.0, 0.0, 0.0])  # z in [0, h]
    cube = m3d.Manifold.cube([4.0, 4.0, 4.0], center=True).translate([0.0, 0.0, -7.0])
    ps = [_part(2, box, "a"), _part(2, prism, "b"), _part(4, cube, "c")]
    rho = 2000.0
    mass, centers = drive_mass.link_mass_properties(ps, rho)
    v_box, v_prism = 6000.0, 0.5 * n * r * r * np.sin(2 * np.pi / n) * h  # mm^3
    m_box, m_prism = v_box * 1e-9 * rho, v_prism * 1e-9 * rho
    # manifold3d meshes are float32
    assert mass == pytest.approx([0, 0, m_box + m_prism, 0, 64e-9 * rho, 0], rel=1e-6)
    c2 = (m_box * np.array([6.0, 12.0, 18.0]) + m_prism * np.array([40.0, 0.0, h / 2])) \
        / (m_box + m_prism) * 1e-3
    assert centers[2] == pytest.approx(c2, abs=1e-9)
    assert centers[4] == pytest.approx([0.0, 0.0, -7e-3], abs=1e-9)
    assert not centers[[0, 1, 3, 5]].any()
    with pytest.raises(ValueError, match="density"):
        drive_mass.link_mass_properties(ps, 0.0)


@pytest.mark.parametrize(("resting", "motor"), [(0, 1), (3, 4)])
def test_torque_is_the_slope_of_the_parts_potential_energy(resting, motor):
    """Independent check of the frames: each part's mesh is moved by its link's pose relative
    to the resting link (mm) and its centre of mass taken there; the potential energy
    ``g sum m z`` differenced in the motor angle equals the reported torque."""
    asm = example_assembly()
    meshes = [export.part_trimesh(p) for p in asm.parts]
    mass, centers = drive_mass.link_mass_properties(asm.parts, 1240.0)
    theta = np.linspace(0.3, 2 * np.pi - 0.3, 9)
    tq = drive_mass.gravity_torque(asm, mass, centers, resting, motor, theta).torque
    a, b = asm.joint_factors[motor, 0], np.linalg.norm(asm.joint_factors[motor, 1:4])

    def energy(th: np.ndarray) -> np.ndarray:  # J, at motor angles th
        poses = dq.to_matrix(loops.link_poses(asm.joint_factors, a - b / np.tan(th / 2)))
        poses[..., :3, 3] *= asm.scale  # mm
        rel = np.linalg.inv(poses[:, resting, None]) @ poses
        z = [[tm.copy().apply_transform(rel[k, link]).center_mass[2] * 1e-3
              for link, tm in zip((p.link for p in asm.parts), meshes, strict=True)]
             for k in range(len(th))]
        return 9.81 * np.array(z) @ mass

    step = 1e-4
    fd = (energy(theta + step) - energy(theta - step)) / (2 * step)
    assert np.abs(tq).max() > 1e-4  # a real torque, not zeros
    assert tq == pytest.approx(fd, abs=1e-6 * np.abs(fd).max())


def test_export_reports_the_drive(tmp_path, capsys):
    """``paraloop export`` of a bundled design: the report's ``drive`` entry (strict JSON)
    for the grounded link, positive masses, a finite torque, the line printed."""
    from app.cli import export as export_cmd

    parser = argparse.ArgumentParser()
    export_cmd.register(parser.add_subparsers())
    args = parser.parse_args(["export", "assets/designs/sun-disc.json", "--out", str(tmp_path),
                              "--size-mm", "500", "--samples", "8", "--quiet"])
    assert args.func(args) in (0, 3)  # 3: 8 samples may leave a gap unproven
    report = json.loads((tmp_path / "report.json").read_text())
    d, rest = report["drive"], report["grounding"]["link"]
    assert d["resting_link"] == rest and d["density_kg_m3"] == 1240.0
    assert min(d["link_masses_kg"]) > 0 and len(d["link_masses_kg"]) == 6
    assert d["moving_mass_kg"] == pytest.approx(sum(d["link_masses_kg"]) -
                                                d["link_masses_kg"][rest], rel=1e-5)
    assert 0 < d["peak_torque_n_m"] < np.inf
    assert len(d["torque_n_m"]) == len(d["theta_rad"]) <= 129
    assert d["peak_torque_n_m"] >= np.abs(d["torque_n_m"]).max() * (1 - 1e-5)
    assert np.isfinite(d["torque_n_m"]).all() and np.ptp(d["torque_n_m"]) > 0
    assert drive_mass.drive_line(d) in capsys.readouterr().out
    assert "N*m" in drive_mass.drive_line(d) and "PLA 1240 kg/m^3" in drive_mass.drive_line(d)


def test_drive_settings_choose_motor_and_density():
    """The design's motor is used as given; the torque scales with the density; without a
    motor the recommended one for the resting link."""
    asm = example_assembly()
    base = drive_mass.drive_entry(asm, 2)
    assert base["motor"] == drive.recommend_motor(asm.joint_factors, 2).motor
    assert base["motor_chosen"] == "recommended"
    other = drive_mass.drive_entry(asm, 2, DriveSettings(motor=5, density_kg_m3=2480.0))
    assert other["motor"] == 5 and other["motor_chosen"] == "design"
    same = drive_mass.drive_entry(asm, 2, DriveSettings(motor=5))
    assert other["moving_mass_kg"] == pytest.approx(2 * same["moving_mass_kg"], rel=1e-12)
    assert other["peak_torque_n_m"] == pytest.approx(2 * same["peak_torque_n_m"], rel=1e-12)
    assert "density 2480 kg/m^3" in drive_mass.drive_line(other)


def test_drive_line_says_why_when_the_torque_is_missing():
    assert drive_mass.drive_line({"error": "part x is not a closed solid: no mass"}) == \
        "motor torque not computed: part x is not a closed solid: no mass"
    assert drive_mass.material(1240) == "PLA 1240 kg/m^3"
    assert drive_mass.material(1000.0) == "density 1000 kg/m^3"
