"""How much the printed links bend: beam estimates per link (report, sizing gaps).

Each bar is a regular hexagonal prism of corner radius ``R`` (mm): area ``3 sqrt(3) R^2 / 2``,
second moment ``5 sqrt(3) R^4 / 16`` about every centroidal axis (a regular hexagon's is
isotropic), so the estimate does not depend on how the bar is turned. With the material's
as-printed modulus ``E`` (the low end of its range, :mod:`profiles`) and a bar of length ``L``
between its joints:

* **sag**: self-weight as a simply supported beam in the worst pose of the cycle,
  ``5 q L^4 / (384 E I)``, ``q = rho g A |sin(angle to the vertical)|`` maximised over the
  cycle (the link as the grounded sculpture moves it);
* **torque**: the motor's peak torque ``tau`` bending the link as end moments (a link of a
  closed loop is held at both ends by its joints; the moment each joint passes on is of the
  order of the motor's torque): ``tau L^2 / (8 E I)`` at mid-span;
* the grounding rod: a cantilever carrying the moving links' weight at their worst lever.

These are engineering estimates (a closed loop shares its loads in ways a beam per link does
not see), stated as such in the report; the sizing keeps every gap between links that do not
share a joint at least ``max(1 mm, 3 x (deflection of one + deflection of the other))``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from paraloop_core.linkage import drive

G = 9.81
#: Smallest gap (mm) between links that do not share a joint, whatever the deflection.
MIN_GAP_MM = 1.0
#: Gap per predicted deflection.
GAP_PER_DEFLECTION = 3.0


def hex_area(r_mm: np.ndarray) -> np.ndarray:
    """Section area (mm^2) of a regular hexagon of corner radius ``r_mm``."""
    return 1.5 * np.sqrt(3.0) * np.square(r_mm)


def hex_inertia(r_mm: np.ndarray) -> np.ndarray:
    """Second moment of area (mm^4) of a regular hexagon of corner radius ``r_mm``."""
    return 5.0 * np.sqrt(3.0) / 16.0 * np.asarray(r_mm, float) ** 4


@dataclass(frozen=True)
class Deflection:
    """Per link ``(6,)`` (mm): ``sag`` under self-weight in the worst pose, ``torque`` under
    the motor's peak torque, ``total`` their sum; ``lengths`` (mm) and ``radii`` (mm) used."""

    sag: np.ndarray
    torque: np.ndarray
    lengths: np.ndarray
    radii: np.ndarray

    @property
    def total(self) -> np.ndarray:
        return self.sag + self.torque


def deflections(lengths_mm: np.ndarray, radii_mm: np.ndarray, across_gravity: np.ndarray,
                modulus_gpa: float, density_g_cm3: float, torque_nm: float) -> Deflection:
    """:class:`Deflection` of bars of ``lengths_mm`` ``(6,)`` and corner ``radii_mm`` ``(6,)``;
    ``across_gravity`` ``(6,)`` the largest ``|sin|`` of the angle between each bar and the
    vertical over the cycle; ``torque_nm`` the motor's peak torque."""
    length = np.asarray(lengths_mm, float)
    r = np.asarray(radii_mm, float)
    e = modulus_gpa * 1e3  # N/mm^2
    ei = e * hex_inertia(r)  # N mm^2
    q = density_g_cm3 * 1e-6 * G * hex_area(r) * np.asarray(across_gravity, float)  # N/mm
    sag = 5.0 * q * length**4 / (384.0 * ei)
    torque = abs(torque_nm) * 1e3 * length**2 / (8.0 * ei)
    return Deflection(sag, torque, length, r)


def radius_for(deflection_mm: float, lengths_mm: np.ndarray, modulus_gpa: float,
               density_g_cm3: float, torque_nm: float) -> np.ndarray:
    """Least hex corner radius ``(6,)`` (mm) whose :func:`deflections` total is at most
    ``deflection_mm``: ``a / R^2 + b / R^4 = delta`` (sag, torque) solved in ``1 / R^2``."""
    length = np.asarray(lengths_mm, float)
    e = modulus_gpa * 1e3
    i_per = 5.0 * np.sqrt(3.0) / 16.0  # I = i_per R^4
    a = 5.0 * density_g_cm3 * 1e-6 * G * 1.5 * np.sqrt(3.0) * length**4 / (384.0 * e * i_per)
    b = abs(torque_nm) * 1e3 * length**2 / (8.0 * e * i_per)
    d = float(deflection_mm)
    # the positive root of b x^2 + a x = d in the form without cancellation (a small torque
    # made (sqrt(a^2 + 4bd) - a) / 2b lose every digit)
    x = 2.0 * d / np.maximum(np.sqrt(a * a + 4.0 * b * d) + a, 1e-300)
    return 1.0 / np.sqrt(x)


def required_gaps(total_mm: np.ndarray) -> np.ndarray:
    """Gap (mm) ``(6, 6)`` two links must keep: ``max(1 mm, 3 (d_a + d_b))``; two links of
    one joint only the least gap (they meet at the joint, where neither bends: its hardware
    holds them, and their bars part from it)."""
    d = np.asarray(total_mm, float)
    gaps = np.maximum(MIN_GAP_MM, GAP_PER_DEFLECTION * (d[:, None] + d[None, :]))
    i = np.arange(6)
    gaps[i, (i + 1) % 6] = gaps[(i + 1) % 6, i] = MIN_GAP_MM
    return gaps


def gap_closed(total_mm: np.ndarray, pairs: list[dict]) -> dict | None:
    """The pair of links without a common joint whose verified gap over the cycle (a
    verification's ``pairs``, :func:`check.verify`: ``continuous_min_gap_mm``, the sound
    bound) is furthest under :func:`required_gaps` of the deflections ``total_mm`` ``(6,)``
    (JSON-ready: links, their deflections, gap, gap required), or None where every gap
    keeps them."""
    need, worst = required_gaps(total_mm), None
    for p in pairs:
        a, b = p["links"]
        short = need[a, b] - p["continuous_min_gap_mm"]
        if not p["adjacent"] and short > 1e-9 and (worst is None or short > worst[0]):
            worst = (short, {"links": [a, b], "deflection_mm": [float(total_mm[a]),
                                                                 float(total_mm[b])],
                             "gap_mm": p["continuous_min_gap_mm"],
                             "required_gap_mm": float(need[a, b])})
    return None if worst is None else worst[1]


def rod_deflection(length_mm: float, d_mm: float, modulus_gpa: float, weight_n: float,
                   lever_mm: float) -> float:
    """Sideways deflection (mm) of the grounding rod's top: a cantilever of ``length_mm``
    carrying ``weight_n`` at ``lever_mm`` from its axis (a moment ``W e``: ``M L^2 / 2EI``)."""
    ei = modulus_gpa * 1e3 * np.pi * d_mm**4 / 64.0
    return float(weight_n * lever_mm * length_mm**2 / (2.0 * ei))


def across_gravity(joint_factors: np.ndarray, bars: list[np.ndarray], resting: int,
                   up: np.ndarray, samples: int = 360) -> np.ndarray:
    """Largest ``|sin|`` ``(6,)`` of the angle between each link's (first) bar and the vertical
    over the cycle, with link ``resting`` still and ``up`` the vertical in its home frame."""
    from paraloop_core.algebra import dq, poly
    from paraloop_core.linkage import loops

    u = np.arange(samples) / samples
    m = dq.to_matrix(loops.link_poses(np.asarray(joint_factors, float), poly.param_to_t(u)))
    rel = np.linalg.inv(m[:, resting, None]) @ m  # (T, 6, 4, 4)
    d = np.array([b[0][1] - b[0][0] for b in bars], float)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    z = np.einsum("i,tlij,lj->tl", np.asarray(up, float), rel[:, :, :3, :3], d)
    return np.sqrt(np.clip(1.0 - np.min(z * z, axis=0), 0.0, 1.0))


def to_dict(d: Deflection, modulus_gpa: float, torque_nm: float | None) -> dict:
    """JSON-ready per-link figures with the method stated (``torque_nm`` None: the loop is
    turned by hand, no motor; torque deflections null)."""
    return {"links": [{"link": i, "length_mm": float(d.lengths[i]),
                       "width_mm": float(np.sqrt(3.0) * d.radii[i]),
                       "length_per_width": float(d.lengths[i] / (np.sqrt(3.0) * d.radii[i])),
                       "sag_mm": float(d.sag[i]),
                       "torque_deflection_mm": None if torque_nm is None else float(d.torque[i])}
                      for i in range(len(d.sag))],
            "modulus_gpa": modulus_gpa, "motor_torque_nm": torque_nm,
            "method": "beam estimates: self-weight sag of a simply supported hexagonal bar in "
                      "its most horizontal pose of the cycle, and the motor's peak torque as "
                      "end moments on the bar (mid-span deflection; none where no motor can "
                      "hold the loop, or its torque would bend two links into the gap they "
                      "keep, and it is turned by hand); as-printed modulus at the low "
                      "end of the material's range"}


def torque_matrix(real) -> np.ndarray:
    """``(6, T, 6)``: for each resting link, the quasi-static motor torque (N m) of its
    recommended motor at ``T`` motor angles per kilogram at each link's bar middle, the loop
    at 1 mm per design unit. The torque is linear in the masses and in the scale, so
    :func:`torque_bound` is a product."""
    pts = np.asarray(real.points, float)
    centers = (pts[0::2] + pts[1::2]) / 2 * 1e-3  # m at 1 mm per unit
    theta = np.linspace(0.0, 2 * np.pi, 64, endpoint=False)
    out = np.zeros((6, len(theta), 6))
    for rest in range(6):
        motor = drive.recommend_motor(real.joint_factors, rest).motor
        for link in range(6):
            if link == rest:
                continue
            unit = np.zeros(6)
            unit[link] = 1.0
            out[rest, :, link] = drive.motor_torque(real.joint_factors, motor, unit, centers,
                                                    length_unit_m=1e-3, resting_link=rest,
                                                    theta=theta).torque
    return out


def torque_bound(real, k: float, radius: np.ndarray, boss: np.ndarray, density: float,
                 matrix: np.ndarray, rest: int | None = None) -> float:
    """An estimate (N m) of the motor's peak torque against gravity of parts with bar corner
    radii ``radius`` ``(6,)`` and bosses ``boss`` ``(6,)`` (mm) at ``k`` mm per unit: each
    link's mass (bar and half of both its joints) at its bar's middle, link ``rest`` resting
    with its recommended motor (None: the worst over every link resting) (:func:`torque_matrix`)."""
    pts = np.asarray(real.points, float)
    length = np.linalg.norm(pts[1::2] - pts[0::2], axis=-1) * k
    pin = np.linalg.norm(pts[1::2] - np.roll(pts[0::2], -1, axis=0), axis=-1) * k
    hub = np.pi * np.square(boss) * (pin + 4 * boss) / 2  # half of each of its two joints
    vol = hex_area(radius) * length + hub + np.roll(hub, 1)
    mass = vol * density * 1e-6  # kg: mm^3 x g/cm^3
    m = matrix if rest is None else matrix[rest:rest + 1]
    return float(np.max(np.abs(m @ mass)) * k)


def easiest_rest(real, matrix: np.ndarray) -> int:
    """The resting link whose recommended motor lifts the loop with the least peak torque
    (bars of equal section): the grounding the sizing plans for, the base prefers it."""
    pts = np.asarray(real.points, float)
    mass = np.linalg.norm(pts[1::2] - pts[0::2], axis=-1)
    return int(np.argmin(np.abs(matrix @ mass).max(axis=1)))
