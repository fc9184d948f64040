"""Motor torque of the printed parts: link masses from the exported meshes, under gravity.

Each part (mm, home frame, :class:`parts.Part`) belongs to one link: the grounding column and
its foot to the grounded link, the end-effector body to link 3 (:func:`parts.build_assembly`
joins them into those links' parts). A link's mass is ``sum volume * density`` of its parts
and its centre of mass their mass-weighted centroid (trimesh mass properties), in metres in
the base frame at home. :func:`drive.motor_torque` then gives the quasi-static torque the
motor joint must supply over one cycle with the resting (grounded) link held still.

World frame: the printed sculpture standing on the ground. The grounding column runs from
the grounded link down to the plane ``z = ground_z`` of that link's home frame
(:mod:`grounding`: home configuration, z up), so the world is the resting link's home frame
(``T_world_base`` = identity: at home every link frame is the base frame) and gravity is
world -z. Without a column the resting link is link 0 in the same frame.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import trimesh

from paraloop_core.design import DriveSettings
from paraloop_core.fabrication.export import part_trimesh
from paraloop_core.fabrication.parts import Assembly, Part
from paraloop_core.linkage import drive

#: Gravity (m/s^2) in the world frame (module docstring: z up, as the grounding column).
GRAVITY_WORLD = np.array([0.0, 0.0, -9.81])
#: Motor angles of the torque curve in the report: ``2 pi k / CURVE_SAMPLES``.
CURVE_SAMPLES = 128
#: Names shown for densities (kg/m^3) of common print materials.
MATERIALS = {1240.0: "PLA"}


def link_mass_properties(parts: Sequence[Part], density_kg_m3: float,
                         meshes: Mapping[str, trimesh.Trimesh] | None = None
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Link masses ``(6,)`` (kg) and centres of mass ``(6, 3)`` (m, the parts' home frame) of
    ``parts`` (mm) at ``density_kg_m3``; ``meshes``: the parts' trimeshes by name if already
    made (:func:`export.part_trimesh`). A link without parts has mass 0, centre 0."""
    rho = drive.check_positive("density_kg_m3", density_kg_m3)
    mass, moment = np.zeros(6), np.zeros((6, 3))  # kg, kg m
    for p in parts:
        tm = meshes[p.name] if meshes is not None and p.name in meshes else part_trimesh(p)
        if not tm.is_volume:
            raise ValueError(f"{p.name} is not a closed solid: no mass")
        m = tm.volume * 1e-9 * rho  # mm^3 -> m^3
        mass[p.link] += m
        moment[p.link] += m * np.asarray(tm.center_mass) * 1e-3  # mm -> m
    centers = np.divide(moment, mass[:, None], out=np.zeros((6, 3)), where=mass[:, None] > 0)
    return mass, centers


def gravity_torque(asm: Assembly, masses_kg: np.ndarray, centers_home_m: np.ndarray,
                   resting_link: int, motor: int, theta: np.ndarray | None = None
                   ) -> drive.MotorTorque:
    """:func:`drive.motor_torque` of ``asm``'s loop (design units, ``asm.scale`` mm each) with
    link masses ``(6,)`` kg and centres ``(6, 3)`` m (home), ``resting_link`` on the ground,
    gravity :data:`GRAVITY_WORLD` in its home frame; at ``theta`` (rad) or adaptive samples."""
    return drive.motor_torque(asm.joint_factors, motor, masses_kg, centers_home_m,
                              GRAVITY_WORLD, None, length_unit_m=asm.scale * 1e-3,
                              theta=theta, resting_link=resting_link)


def drive_entry(asm: Assembly, resting_link: int, settings: DriveSettings | None = None,
                meshes: Mapping[str, trimesh.Trimesh] | None = None) -> dict:
    """The report's ``drive`` entry (JSON-ready): the motor (``settings.motor``, else
    :func:`drive.recommend_motor` for ``resting_link``), density (kg/m^3), link masses (kg),
    moving mass (kg), peak |torque| (N m, over the adaptive samples of
    :func:`drive.motor_torque`) and the torque curve at :data:`CURVE_SAMPLES` motor angles."""
    settings = DriveSettings() if settings is None else settings
    motor = settings.motor
    if motor is None:
        motor = drive.recommend_motor(asm.joint_factors, resting_link).motor
    mass, centers = link_mass_properties(asm.parts, settings.density_kg_m3, meshes)
    peak = gravity_torque(asm, mass, centers, resting_link, motor)
    theta = np.arange(CURVE_SAMPLES) * (drive.TWO_PI / CURVE_SAMPLES)
    curve = gravity_torque(asm, mass, centers, resting_link, motor, theta)
    return {"motor": int(motor), "motor_chosen": "recommended" if settings.motor is None
            else "design", "resting_link": int(resting_link),
            "density_kg_m3": float(settings.density_kg_m3),
            "link_masses_kg": [float(f"{m:.6g}") for m in mass],
            "moving_mass_kg": peak.moving_mass_kg, "peak_torque_n_m": peak.peak_torque,
            "theta_rad": [round(float(t), 6) for t in theta],
            "torque_n_m": [float(f"{t:.6g}") for t in curve.torque],
            "gravity_m_s2": GRAVITY_WORLD.tolist(),
            "method": "quasi-static (virtual work) torque against gravity, world -z = down "
                      "the grounding column, the resting link held still; masses from the "
                      "exported meshes at the density; no inertia, no friction"}


def material(density_kg_m3: float) -> str:
    """``'PLA 1240 kg/m^3'`` for a known print material's density, else ``'density 1000
    kg/m^3'``."""
    rho = float(density_kg_m3)
    return f"{MATERIALS.get(rho, 'density')} {rho:g} kg/m^3"


def drive_line(entry: dict) -> str:
    """One line for people: motor joint, peak torque, moving mass, density (a report's
    ``drive`` entry, :func:`drive_entry`, or why it is missing)."""
    if "error" in entry:
        return f"motor torque not computed: {entry['error']}"
    return (f"motor joint {entry['motor']} (resting link {entry['resting_link']}): peak torque "
            f"{entry['peak_torque_n_m']:.3g} N*m for {entry['moving_mass_kg']:.3g} kg moving "
            f"({material(entry['density_kg_m3'])})")
