"""Motor torque of the printed loop: link masses from the built parts and hardware, under gravity.

Each link's mass and centre of mass come from its printed parts (exact mesh volumes x the
material's density) and the steel hardware it carries (:func:`base.link_masses`); the base
and the rod belong to the grounded link, which rests. :func:`drive.motor_torque` then gives
the quasi-static torque the motor joint must supply over one cycle.

Gravity: the printed sculpture standing on its base, ``-9.81 up`` in the resting (grounded)
link's home frame (``up`` along its rod, :mod:`base`).
"""

from __future__ import annotations

import numpy as np

from paraloop_core.design import DriveSettings
from paraloop_core.fabrication.profiles import MATERIALS, Material
from paraloop_core.linkage import drive

#: Motor angles of the torque curve in the report: ``2 pi k / CURVE_SAMPLES``.
CURVE_SAMPLES = 128


def gravity_torque(joint_factors: np.ndarray, scale: float, masses_g: np.ndarray,
                   centers_mm: np.ndarray, resting_link: int, motor: int,
                   theta: np.ndarray | None = None, up: np.ndarray = (0.0, 0.0, 1.0)
                   ) -> drive.MotorTorque:
    """:func:`drive.motor_torque` of the loop ``joint_factors`` (design units, ``scale`` mm
    each) with link masses ``(6,)`` (g) at home centres ``(6, 3)`` (mm), ``resting_link``
    still, ``up`` the vertical in its home frame; at ``theta`` (rad) or adaptive samples."""
    gravity = -9.81 * np.asarray(up, float) / np.linalg.norm(up)
    return drive.motor_torque(joint_factors, motor, np.asarray(masses_g, float) * 1e-3,
                              np.asarray(centers_mm, float) * 1e-3, gravity, None,
                              length_unit_m=scale * 1e-3, theta=theta,
                              resting_link=resting_link)


def entry(joint_factors: np.ndarray, scale: float, masses_g: np.ndarray,
          centers_mm: np.ndarray, resting_link: int, settings: DriveSettings | None,
          material: Material, up: np.ndarray = (0.0, 0.0, 1.0)) -> dict:
    """The report's ``drive`` entry (JSON-ready): the motor (the design's, else
    :func:`drive.recommend_motor` for ``resting_link``), link masses (kg), moving mass,
    peak |torque| (N m) and the torque curve at :data:`CURVE_SAMPLES` motor angles; on a
    planner error ``{"error": ...}`` (the parts are verified: a torque that cannot be computed
    says why, it never fails them)."""
    settings = DriveSettings() if settings is None else settings
    try:
        motor = settings.motor
        if motor is None:
            motor = drive.recommend_motor(joint_factors, resting_link).motor
        peak = gravity_torque(joint_factors, scale, masses_g, centers_mm, resting_link, motor,
                              up=up)
        theta = np.arange(CURVE_SAMPLES) * (drive.TWO_PI / CURVE_SAMPLES)
        curve = gravity_torque(joint_factors, scale, masses_g, centers_mm, resting_link, motor,
                               theta, up)
    except ValueError as exc:
        return {"error": str(exc)}
    return {"motor": int(motor), "motor_chosen": "recommended" if settings.motor is None
            else "design", "resting_link": int(resting_link), "material": material.name,
            "density_kg_m3": material.density_g_cm3 * 1e3,
            "link_masses_kg": [float(f"{m * 1e-3:.6g}") for m in masses_g],
            "moving_mass_kg": peak.moving_mass_kg, "peak_torque_n_m": peak.peak_torque,
            "worst_speed_ratio": float(drive.smooth_drive_penalty(joint_factors, motor)),
            "theta_rad": [round(float(t), 6) for t in theta],
            "torque_n_m": [float(f"{t:.6g}") for t in curve.torque],
            "gravity_home_m_s2": (-9.81 * np.asarray(up, float)).tolist(),
            "method": "quasi-static (virtual work) torque against gravity, the grounded link "
                      "resting, the sculpture standing on its base; masses of the printed "
                      "parts and hardware; no inertia, no friction"}


def material(density_kg_m3: float) -> str:
    """``'PLA 1240 kg/m^3'`` for a known print material's density, else ``'density 1000
    kg/m^3'``."""
    rho = float(density_kg_m3)
    name = next((m.name for m in MATERIALS.values() if abs(m.density_g_cm3 * 1e3 - rho) < 1e-6),
                "density")
    return f"{name} {rho:g} kg/m^3"


def hand_reason(entry: dict) -> str | None:
    """Why a report's ``drive`` entry (:func:`entry`) has the loop turned by hand, or None
    (a motor drives it): one motor cannot hold the loop (its worst speed ratio past
    :data:`drive.HOLD_RATIO`), the printed loop is near-singular (``near_singular``), or the
    motor's peak torque would bend two links without a common joint closer than the gap
    they keep allows (``motor_bends``; both set by the export: :func:`printable.make`)."""
    ratio = entry.get("worst_speed_ratio", 0.0)
    if too_slow(entry):
        return (f"in part of its turn the motor's joint would move {ratio:.0f} times slower "
                "than the fastest joint, so no motor holds the loop there (its links swing "
                "under gravity)")
    if entry.get("near_singular"):
        return ("the printed loop passes close to a singular configuration (no realization "
                "of a loop farther from one was sized), where a motor on one joint can let it "
                "switch to another branch of its motion (MuJoCo: random design 62232's loop 8 "
                "did)")
    bent = entry.get("motor_bends")
    if bent:
        (a, b), (da, db) = bent["links"], bent["deflection_mm"]
        return (f"the motor's peak torque ({entry['peak_torque_n_m']:.2g} N m on joint "
                f"{entry['motor']}) would bend links {a} and {b} by {da:.1f} and {db:.1f} mm, "
                f"and the {bent['gap_mm']:.1f} mm they keep apart over the cycle is less than "
                f"the {bent['required_gap_mm']:.0f} mm (3 x that) that would keep them apart")
    return None


def too_slow(entry: dict) -> bool:
    """Whether the motor's joint of a ``drive`` entry nearly stops in part of the turn (its
    worst speed ratio past :data:`drive.HOLD_RATIO`): no motor holds the loop there."""
    return entry.get("worst_speed_ratio", 0.0) > drive.HOLD_RATIO


def by_hand(entry: dict) -> bool:
    """Whether a report's ``drive`` entry says to turn the loop by hand (:func:`hand_reason`)."""
    return hand_reason(entry) is not None


def drive_line(entry: dict) -> str:
    """One line for people: motor joint, peak torque, moving mass, material (a report's
    ``drive`` entry, :func:`entry`, or why it is missing)."""
    if "error" in entry:
        return f"motor torque not computed: {entry['error']}"
    why = hand_reason(entry)
    if why is not None:
        return (f"turn it by hand (holding the base and a link across the loop): "
                f"{why}; {entry['moving_mass_kg']:.3g} kg moving "
                f"({material(entry['density_kg_m3'])})")
    return (f"motor joint {entry['motor']} (resting link {entry['resting_link']}): peak torque "
            f"{entry['peak_torque_n_m']:.3g} N*m for {entry['moving_mass_kg']:.3g} kg moving "
            f"({material(entry['density_kg_m3'])})")
