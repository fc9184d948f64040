"""Printer profiles and the automatic size: the thickest parts the certificate allows.

The realization proves, over the whole cycle, a lower bound ``L_ef`` (design units) of the
distance between each pair of its 12 centre segments that must stay apart
(``Realization.pair_lower``: bars ``S_iE_i`` and pins ``E_iS_{i+1}`` of different links) and of
each pair of consecutive bars (``joint_lower``). A part lies within a capsule about its
segments: radius ``R_bar`` about its bar, ``R_boss`` (the joint hardware) about its pins. So at
``k`` mm per unit the parts keep ``c`` mm apart if

* ``2 R_bar + c <= k L`` for bar-bar pairs (consecutive bars included),
* ``R_bar + R_boss + c <= k L`` for bar-pin pairs, ``2 R_boss + c <= k L`` for pin-pin pairs,
and a printer needs ``R_bar >= wall / 2`` (the bar is one wall thick),
``R_boss >= pin + c + wall`` (a pin of the profile's radius in a bore with a wall around it)
and ``k P >= 2 wall + c`` for the shortest pin ``P`` (the two bosses on a pin, each a wall
thick, with the clearance between them).
Each constraint is linear in ``k``: the smallest size follows in closed form, and at any larger
size the radii grow to the certified limits, bosses first (the pin in its bore is the weak
spot; at most :data:`BOSS_CAP` of the size), then bars up to :data:`BAR_TO_BOSS` of the
boss (and :data:`BAR_CAP` of the size). The export's own interference check then
re-verifies the built parts over the cycle.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from paraloop_core.errors import FabricationError

#: Preferred longest side of the linkage (mm) when the profile allows it.
PREFERRED_SIZE_MM = 150.0
#: Largest bar radius as a fraction of the boss radius.
BAR_TO_BOSS = 0.75
#: Largest boss radius as a fraction of the size (beyond the profile's minimum): thicker is
#: not stronger where it only adds mass, and hubs wider than the pins are long crowd the joint.
BOSS_CAP = 0.012
#: Largest bar radius as a fraction of the size (beyond the profile's minimum).
BAR_CAP = 0.004


@dataclass(frozen=True)
class Printer:
    """A printer profile: ``bed_mm`` (x, y, z build volume), thinnest ``wall_mm``, smallest
    ``pin_radius_mm`` and the joint ``clearance_mm`` (radial pin/bore and axial gaps)."""

    name: str
    bed_mm: tuple[float, float, float]
    wall_mm: float = 2.0
    pin_radius_mm: float = 1.0
    clearance_mm: float = 0.3

    def __post_init__(self) -> None:
        vals = (*self.bed_mm, self.wall_mm, self.pin_radius_mm)
        if len(self.bed_mm) != 3 or not all(np.isfinite(v) and v > 0 for v in vals) \
                or not (np.isfinite(self.clearance_mm) and self.clearance_mm >= 0):
            raise FabricationError(f"printer {self.name!r}: bed, wall and pin must be > 0 mm and "
                                   f"the clearance >= 0 mm, got {self}", "bad-parameters")


#: Common desktop printers (build volumes from the makers' data sheets, mm).
PRINTERS = {p.name: p for p in (
    Printer("generic", (250.0, 210.0, 210.0)),
    Printer("prusa-mk4", (250.0, 210.0, 220.0)),
    Printer("prusa-mini", (180.0, 180.0, 180.0)),
    Printer("bambu-x1", (256.0, 256.0, 256.0)),
    Printer("bambu-a1-mini", (180.0, 180.0, 180.0)),
    Printer("ender-3", (220.0, 220.0, 250.0)),
)}


@dataclass(frozen=True)
class Limits:
    """Certified distance bounds (design units) by pair type and the polyline's extent."""

    bar_bar: float
    bar_pin: float
    pin_pin: float
    extent: float
    #: shortest pin ``E_i S_{i+1}``
    pin_length: float


@dataclass(frozen=True)
class Sizing:
    """The chosen size (mm, longest side of the polyline), ``scale`` (mm per unit), the part
    radii (mm), the smallest size meeting the profile and the constraint that sets it."""

    size_mm: float
    scale: float
    bar_radius_mm: float
    boss_radius_mm: float
    pin_radius_mm: float
    min_size_mm: float
    binding: str


def limits(points: np.ndarray, pairs: np.ndarray, pair_lower: np.ndarray,
           joint_lower: np.ndarray) -> Limits:
    """:class:`Limits` of a realization: ``points`` ``(12, 3)``, ``pairs`` ``(N, 4)`` (edge,
    edge, link, link; even edges are bars) with proven ``pair_lower`` ``(N,)`` and the proven
    ``joint_lower`` ``(6,)`` of the consecutive bars."""
    pts = np.asarray(points, float)
    e = np.asarray(pairs)[:, :2] % 2 == 0
    low = np.asarray(pair_lower, float)
    if not (np.all(np.isfinite(low)) and np.all(np.isfinite(joint_lower))):
        raise FabricationError("the realization has no proven pair bounds", "bad-parameters")
    bb = min(low[e[:, 0] & e[:, 1]].min(initial=np.inf), float(np.min(joint_lower)))
    pins = np.linalg.norm(pts[1::2] - np.roll(pts[0::2], -1, axis=0), axis=-1)
    return Limits(bb, low[e[:, 0] != e[:, 1]].min(initial=np.inf),
                  low[~e[:, 0] & ~e[:, 1]].min(initial=np.inf),
                  float(np.max(np.ptp(pts, axis=0))), float(pins.min()))


def realization_limits(real: Any) -> Limits:
    """:func:`limits` of a ``certified.Realization`` (its points, pairs and proven bounds)."""
    return limits(real.points, real.pairs, real.pair_lower, real.joint_lower)


def choose_size(lim: Limits, printer: Printer, size_mm: float | None = None) -> Sizing:
    """Size and radii (module docstring): ``size_mm`` if given (refused when below the
    profile's minimum), else :data:`PREFERRED_SIZE_MM` raised to the minimum if needed."""
    c, wall = printer.clearance_mm, printer.wall_mm
    bar_min, boss_min = wall / 2.0, printer.pin_radius_mm + c + wall
    need = {  # smallest k (mm per unit) of each constraint
        "bar-bar clearance": (2 * bar_min + c) / lim.bar_bar,
        "bar-boss clearance": (bar_min + boss_min + c) / lim.bar_pin,
        "boss-boss clearance": (2 * boss_min + c) / lim.pin_pin,
        "boss thickness on the shortest pin": (2 * wall + c) / max(lim.pin_length, 1e-300),
    }
    binding = max(need, key=need.get)
    min_size = need[binding] * lim.extent
    if size_mm is None:
        size_mm = max(PREFERRED_SIZE_MM, min_size)
    elif size_mm < min_size * (1 - 1e-12):
        raise FabricationError(
            f"at {size_mm:.4g} mm the parts cannot meet the printer profile {printer.name!r} "
            f"(walls {wall} mm, pin radius {printer.pin_radius_mm} mm, clearance {c} mm): the "
            f"{binding} needs at least {np.ceil(min_size):.0f} mm", "bad-parameters")
    k = size_mm / lim.extent
    shared = k * lim.bar_pin - c  # budget of R_bar + R_boss
    # split it as BAR_TO_BOSS (a bar stays thinner than its hubs: the joint zones must
    # contain its section), keeping each above its minimum
    bar = min((k * lim.bar_bar - c) / 2.0, shared - boss_min,
              max(bar_min, shared * BAR_TO_BOSS / (1.0 + BAR_TO_BOSS)))
    boss = min((k * lim.pin_pin - c) / 2.0, shared - bar, max(boss_min, BOSS_CAP * size_mm))
    bar = min(bar, max(bar_min, min(BAR_TO_BOSS * boss, BAR_CAP * size_mm)))
    pin = max(printer.pin_radius_mm, min(0.5 * boss, boss - c - wall))
    return Sizing(float(size_mm), float(k), float(bar), float(boss), float(pin), float(min_size),
                  binding)


#: Turns about the vertical (radians, 0.5 degree steps) tried for a footprint: a long thin
#: part that does not fit the bed square-on may fit diagonally.
TURNS = np.radians(np.arange(0.0, 90.01, 0.5))


def footprint_turn(size_xy: np.ndarray, bed_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(factor, turn)`` ``(...)`` for footprints ``size_xy`` ``(..., 2)`` (mm) on a bed
    ``bed_xy`` ``(2,)``: the largest factor by which a footprint may grow and still fit, turned
    by ``turn`` (radians, one of :data:`TURNS`) about the vertical."""
    w = np.asarray(size_xy, float)[..., None, :]
    c, s = np.cos(TURNS), np.sin(TURNS)
    fx = bed_xy[0] / np.maximum(w[..., 0] * c + w[..., 1] * s, 1e-12)
    fy = bed_xy[1] / np.maximum(w[..., 0] * s + w[..., 1] * c, 1e-12)
    f = np.minimum(fx, fy)
    best = np.argmax(f, axis=-1)
    return np.take_along_axis(f, best[..., None], -1)[..., 0], TURNS[best]


def fit_factor(extents_mm: np.ndarray, printer: Printer) -> np.ndarray:
    """Largest factor ``(P,)`` by which parts with box extents ``(P, 3)`` may grow and still
    fit the bed, the box resting on any of its faces and turned about the vertical (a long bar
    fits diagonally); at least 1 where the part fits."""
    ext = np.asarray(extents_mm, float)
    bed = np.asarray(printer.bed_mm, float)
    best = np.zeros(ext.shape[:-1])
    for up in range(3):  # which box side stands vertical
        flat = np.delete(ext, up, axis=-1)
        f, _ = footprint_turn(flat, bed[:2])
        best = np.maximum(best, np.minimum(f, bed[2] / np.maximum(ext[..., up], 1e-12)))
    return best


def fits_bed(extents_mm: np.ndarray, printer: Printer) -> np.ndarray:
    """Mask ``(P,)``: parts with box extents ``(P, 3)`` fit the bed in some orientation
    (:func:`fit_factor`)."""
    return fit_factor(extents_mm, printer) >= 1.0 - 1e-9
