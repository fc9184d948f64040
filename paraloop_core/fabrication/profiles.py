"""What the parts are made with: printer profiles, print materials and joint hardware.

All lengths in mm, masses in g, moduli in GPa. Figures are the usual catalogue and handbook
values (``docs/fabrication.md`` cites them); a maker with other hardware edits one profile.

* :class:`Printer`: bed (build volume), the thinnest wall the parts keep (around bores, under
  boss faces), the radial clearance of moving printed surfaces, how much printed holes come out
  small (added to every hole), the layer height the guide recommends.
* :class:`Material`: density and the *as-printed* Young's modulus (the low end of the usual
  range, so predicted deflections are upper estimates).
* :class:`Fastener`: an ISO metric screw with its nyloc nut and washers (joint kind ``m3``,
  ``m4``), and :class:`Rod`: the round rod that is the grounding column and the axle of the
  grounded joint.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from paraloop_core.errors import FabricationError

#: Thinnest printed wall anywhere (mm): sheets of an open end-effector are this thick.
MIN_WALL_MM = 0.8


@dataclass(frozen=True)
class Printer:
    """A printer profile (module docstring)."""

    name: str
    bed_mm: tuple[float, float, float]
    wall_mm: float = 1.6
    clearance_mm: float = 0.3
    hole_allowance_mm: float = 0.2
    layer_mm: float = 0.2
    note: str = ""

    def __post_init__(self) -> None:
        vals = (*self.bed_mm, self.wall_mm, self.layer_mm)
        if len(self.bed_mm) != 3 or not all(np.isfinite(v) and v > 0 for v in vals) or not (
                np.isfinite(self.clearance_mm) and 0 <= self.clearance_mm <= 5) or not (
                np.isfinite(self.hole_allowance_mm) and 0 <= self.hole_allowance_mm <= 2):
            raise FabricationError(
                f"printer {self.name!r}: bed, wall and layer must be > 0 mm, the clearance in "
                f"0..5 mm and the hole allowance in 0..2 mm", "bad-parameters")


#: Desktop printers: build volumes from the makers' data sheets; clearances as usually tuned
#: (a calibrated Prusa or Bambu holds 0.2 - 0.25 mm between moving printed faces, a stock
#: Ender-3 about 0.35 mm and prints holes smaller).
PRINTERS = {p.name: p for p in (
    Printer("generic", (250.0, 210.0, 210.0), 1.6, 0.3, 0.2, 0.2,
            "any well-calibrated 0.4 mm nozzle printer"),
    Printer("prusa-mk4", (250.0, 210.0, 220.0), 1.6, 0.25, 0.15, 0.2, "Prusa MK4 / MK4S"),
    Printer("prusa-mini", (180.0, 180.0, 180.0), 1.6, 0.25, 0.15, 0.2, "Prusa MINI+"),
    Printer("bambu-x1", (256.0, 256.0, 256.0), 1.6, 0.2, 0.15, 0.2, "Bambu Lab X1 / P1"),
    Printer("bambu-a1-mini", (180.0, 180.0, 180.0), 1.6, 0.2, 0.15, 0.2, "Bambu Lab A1 mini"),
    Printer("ender-3", (220.0, 220.0, 250.0), 1.8, 0.35, 0.3, 0.2,
            "Creality Ender-3 (stock: looser fits, holes print small)"),
)}


#: Largest build-volume side accepted (mm): a large-format printer, not a typo of units.
MAX_BED_MM = 1e4


def parse_bed(text: str) -> tuple[float, float, float]:
    """A build volume ``"X,Y,Z"`` in mm (each > 0 and at most :data:`MAX_BED_MM`); raises
    FabricationError saying what is accepted."""
    parts = str(text).split(",")
    try:
        bed = tuple(float(v) for v in parts)
    except ValueError:
        bed = ()
    if len(bed) != 3 or not all(np.isfinite(v) and 0 < v <= MAX_BED_MM for v in bed):
        raise FabricationError(f"the bed needs X,Y,Z in mm, each in (0, {MAX_BED_MM:g}], got "
                               f"{str(text)[:60]!r}", "bad-parameters")
    return bed  # type: ignore[return-value]


def printer(name: str, bed_mm: tuple[float, float, float] | None = None,
            clearance_mm: float | None = None) -> Printer:
    """The profile ``name`` of :data:`PRINTERS` with the maker's build volume and clearance
    where given (None: the profile's)."""
    if name not in PRINTERS:
        raise FabricationError(f"unknown printer {name!r} (one of {', '.join(PRINTERS)})",
                               "bad-parameters")
    out = PRINTERS[name]
    if bed_mm is not None:
        out = replace(out, name=f"{out.name}, bed {','.join(f'{v:g}' for v in bed_mm)}",
                      bed_mm=tuple(float(v) for v in bed_mm))
    if clearance_mm is not None:
        out = replace(out, clearance_mm=float(clearance_mm))
    return out


@dataclass(frozen=True)
class Material:
    """A print material: ``density_g_cm3``, as-printed ``modulus_gpa`` (low end) and the
    guide's print notes."""

    name: str
    density_g_cm3: float
    modulus_gpa: float
    nozzle_c: int
    bed_c: int
    note: str


MATERIALS = {m.name.lower(): m for m in (
    Material("PLA", 1.24, 2.3, 210, 60, "stiff; creeps under constant load, keep below 50 C"),
    Material("PETG", 1.27, 1.8, 240, 80, "tougher than PLA, strings more: dry the filament"),
    Material("ABS", 1.05, 1.8, 250, 100, "needs an enclosure; ASA for outdoor pieces"),
)}


@dataclass(frozen=True)
class Fastener:
    """An ISO metric joint screw (ISO 4762 socket head) with a nylon-insert lock nut (DIN 985)
    and washers (ISO 7089); ``hole_mm`` the clearance hole (ISO 273 fine) before the
    printer's allowance (ISO 273 fine: the printed hole comes out near the medium size); stock
    ``lengths_mm`` (ISO 4762 sizes sold in hobby assortments)."""

    name: str
    d_mm: float
    hole_mm: float
    head_d_mm: float
    head_h_mm: float
    nut_af_mm: float
    nut_h_mm: float
    washer_d_mm: float
    washer_t_mm: float
    lengths_mm: tuple[float, ...]

    @property
    def nut_corner_r_mm(self) -> float:
        """Radius over the nut's corners (across flats / cos 30 deg, halved)."""
        return self.nut_af_mm / np.sqrt(3.0)

    @property
    def reach_r_mm(self) -> float:
        """Radius of the hardware beyond the bosses (washer, head, nut corners)."""
        return max(self.washer_d_mm / 2.0, self.head_d_mm / 2.0, self.nut_corner_r_mm)

    def screw_length(self, needed_mm: float) -> float | None:
        """Shortest stock length >= ``needed_mm`` (None: longer than any stock screw)."""
        fit = [v for v in self.lengths_mm if v >= needed_mm - 1e-9]
        return min(fit) if fit else None


FASTENERS = {f.name.lower(): f for f in (
    Fastener("M2", 2.0, 2.2, 3.8, 2.0, 4.0, 2.8, 5.0, 0.3,
             (6.0, 8.0, 10.0, 12.0, 14.0, 16.0, 18.0, 20.0, 25.0, 30.0)),
    Fastener("M3", 3.0, 3.2, 5.5, 3.0, 5.5, 4.0, 7.0, 0.5,
             (8.0, 10.0, 12.0, 14.0, 16.0, 18.0, 20.0, 22.0, 25.0, 30.0, 35.0, 40.0, 45.0, 50.0)),
    Fastener("M4", 4.0, 4.3, 7.0, 4.0, 7.0, 5.0, 9.0, 0.8,
             (10.0, 12.0, 14.0, 16.0, 18.0, 20.0, 22.0, 25.0, 30.0, 35.0, 40.0, 45.0, 50.0, 60.0)),
)}
#: Steel density (g/cm^3) for the hardware's mass.
STEEL_G_CM3 = 7.85


@dataclass(frozen=True)
class Rod:
    """The grounding column: a round rod of ``d_mm`` (``material``, ``modulus_gpa``,
    ``density_g_cm3``), cut to length; it is also the axle of the grounded joint."""

    name: str
    d_mm: float
    modulus_gpa: float
    density_g_cm3: float


RODS = {r.name: r for r in (
    Rod("8 mm aluminium rod", 8.0, 69.0, 2.70),
    Rod("8 mm steel rod", 8.0, 200.0, 7.85),
    Rod("6 mm steel rod", 6.0, 200.0, 7.85),
    Rod("5 mm steel rod", 5.0, 200.0, 7.85),
    # where the thin bars of a grounded joint leave a thicker rod's bore no wall above their
    # print flat (those links would print over supports): a 250 mm column of it leans
    # 0.5 mm under a 2 N loop whose centre of mass sits 30 mm off it
    Rod("4 mm steel rod", 4.0, 200.0, 7.85),
)}
DEFAULT_ROD = RODS["6 mm steel rod"]

#: Joint kinds of ``paraloop export --joints``: ``auto`` (the default: M3, or M2 where M3
#: does not fit the room the certificate leaves), an M2, M3 or M4 screw with a lock nut through
#: both links (metal axle, retained, adjustable), a printed pin with a printed cap pressed on
#: (no hardware), or print-in-place (refused for spatial loops, with the reason).
JOINT_KINDS = ("auto", "m2", "m3", "m4", "printed-pin", "print-in-place")
#: What ``auto`` tries, in order.
AUTO_JOINTS = ("m3", "m2")
#: Printed pin (kind ``printed-pin``): shaft diameter, head height, cap height, the cap's press
#: fit (its hole this much under the shaft) and how deep the shaft enters the cap.
PRINTED_PIN_D_MM = 5.0
PRINTED_HEAD_H_MM = 2.4
PRINTED_CAP_H_MM = 6.0
PRINTED_CAP_PRESS_MM = 0.15
PRINTED_CAP_DEPTH_MM = 4.0
#: Engagement of a pin or screw in each boss, in pin diameters: the issue's floor and the
#: design target (well inside it).
ENGAGE_MIN = 1.5
ENGAGE_TARGET = 2.0


@dataclass(frozen=True)
class Options:
    """What the maker chose (None: the program chooses)."""

    printer: Printer = PRINTERS["generic"]
    material: Material = MATERIALS["pla"]
    joints: str = "auto"  # the CLI's and the studio's default: M3, M2 where M3 does not fit
    rod: Rod = DEFAULT_ROD
    size_mm: float | None = None
    ground: bool = True
    #: the link the grounding rod holds (None: the program chooses)
    ground_link: int | None = None
    samples: int = 720
