"""The joints of the printed loop: bosses, bores and hardware along each joint axis.

Joint j (axis ``A_j``) joins link j (its bar ends at ``E_j``) and link j+1 (its bar starts at
``S_{j+1}``). Along the axis, ``s`` is the distance (mm) from ``E_j`` towards ``S_{j+1}`` (unit
``w``; the pin ``E_j S_{j+1}`` has length ``P``):

* link j's boss is ``s in [-o_lo, m - g/2]``, link j+1's ``[m + g/2, P + o_up]``: the split
  ``m`` (:func:`split_point`) keeps each bar on its own side; ``g`` is the axial gap (the
  thrust washer of a screw joint, the printer's clearance otherwise); the outer extensions
  ``o`` make each boss hold its axle :data:`profiles.ENGAGE_TARGET` diameters;
* kind ``m3``/``m4``: a socket head screw through both bosses (clearance bores), a washer
  under its head on link j's boss's outer face, a thrust washer between the bosses, a washer
  and a nylon-insert lock nut on link j+1's outer face (the insert holds the nut on the
  screw, so the joint neither loosens nor tightens as it turns round and round). The
  hardware sits outside the bosses, not sunk in recesses: a boss then needs a wall only
  around its bore, so a link's print flat can cut its bosses (:mod:`flat`) where a head's
  counterbore or a nut's trap would break open, and no trap has to fit a nut to a tenth of a
  millimetre. The stock screw length is chosen; its tip passes the nut by at least
  :data:`PROTRUDE_MM`;
* kind ``printed-pin``: a printed pin (head + shaft) through both bosses, a printed cap
  pressed on its end;
* kind ``dowel`` (chosen by :func:`layout` for a screw joint where one link's bar leaves
  past its boss's outer face, :func:`blocked_sides`: the head or nut would sit inside that
  bar): a steel dowel (the screw's diameter) glued into a blind bore of that link's boss (its
  floor keeps a wall, so the bar goes on whole), turning in the other link's bore, held by a
  printed cap glued on its end outside the other boss; where both bars leave past their
  bosses' outer faces, the other link's bore is blind too, its floor a clearance past the
  dowel's tip (it keeps that link on; the guide fits this joint before the loop closes);
  also where no stock screw spans the bosses (a long joint): then a steel rod of the
  screw's diameter cut to length, glued in link j's boss and capped past link j+1's;
* kind ``rod``: the grounded joint: the grounding rod is the axle, fixed (press fit, glued) in
  the grounded link's boss, turning in the other link's boss, held by a printed cap glued on
  its end (or, where the cap's room would cut the other link's bar, ending in a blind bore
  of that link whose floor keeps it on); beyond the grounded link's boss it goes on down to
  the base (:mod:`base`).

Every piece is a solid of revolution about the axis (the nut by its corner cylinder), so
between the two links of a joint nothing changes with the joint angle, and against any other
link the joint's hardware moves as either of its two links does.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import profiles
from paraloop_core.fabrication.profiles import Fastener, Printer, Rod

#: Radial room (mm) left around the hardware outside a boss (washers, head, nut).
SEAT_MM = 0.3
#: Least boss length (mm) past a joint point, and as a share of the bar's corner radius there
#: (a bar's end standing out past the boss's outer face is trimmed to it).
MIN_OUTER_MM = 0.5
COVER = 0.6
#: Thread (mm) that must pass the lock nut's insert.
PROTRUDE_MM = 1.0
#: Room (mm) a boss keeps beyond its bore's wall (:func:`min_boss_radius`).
BOSS_ROOM_MM = 0.4
#: Roles of the pieces a joint turns on (:attr:`Joint.axle`).
AXLES = ("screw", "pin", "rod", "dowel")
#: How far (mm) a dowel reaches into its glued cap, and the room (mm) the cap keeps over its
#: end beyond the printer's wall (the hole's cut reaches a little past the end): the cap as
#: tall as the nut room the sizing gives a joint.
DOWEL_IN_CAP_MM, DOWEL_CAP_ROOM_MM = 2.3, 0.3
#: How much wider (mm, radius) a glued cap's hole is than the rod or dowel it takes.
GLUED_CAP_SLACK_MM = 0.05


@dataclass(frozen=True)
class Piece:
    """A solid of revolution on a joint axis: ``s in [s0, s1]`` (mm), ``radius`` (the corner
    radius of a hexagon when ``sides == 6``); ``role`` names it in the guide and the bill of
    materials; ``printed`` pieces are separate printed parts (pin, cap)."""

    s0: float
    s1: float
    radius: float
    role: str
    printed: bool = False
    sides: int = 0  # 0: round


@dataclass(frozen=True)
class Joint:
    """One joint's layout (module docstring), mm, home pose."""

    index: int
    kind: str
    origin: np.ndarray
    w: np.ndarray
    length: float
    split: float
    gap: float
    boss_radius: float
    lower: tuple[float, float]
    upper: tuple[float, float]
    bore: tuple[float, float]
    pieces: tuple[Piece, ...]
    axle_d: float
    screw_mm: float | None
    notch: tuple[float, float]
    #: kinds ``rod`` and ``dowel``: the side whose link holds the axle fixed (0: link j,
    #: 1: link j+1); the grounding rod leaves to the base past that link's boss
    rod_side: int | None = None
    #: whether link j's bar (0) and link j+1's (1) are cut across their centre line here
    #: (:func:`cut_sides`): a crescent where a bar should be, to be avoided where it can be
    cut: tuple[bool, bool] = (False, False)
    #: kind ``dowel`` where no stock screw spans the bosses (the axle is a rod cut to
    #: length); otherwise a dowel is where a bar runs on past its boss (:func:`blocked_sides`)
    beyond_stock: bool = False

    def at(self, s: float | np.ndarray) -> np.ndarray:
        """Points ``(..., 3)`` at axial coordinates ``s``."""
        return self.origin + np.multiply.outer(s, self.w)

    @property
    def blind(self) -> bool:
        """Kinds ``rod`` and ``dowel`` without a cap: the axle ends in the turning link's
        blind bore, whose floor keeps that link on (:func:`layout`)."""
        return self.kind in ("rod", "dowel") and not any(p.printed for p in self.pieces)

    @property
    def fixed_link(self) -> int | None:
        """Kinds ``rod`` and ``dowel``: the link holding the axle fixed (else None)."""
        return None if self.rod_side is None else (self.index + self.rod_side) % 6

    @property
    def axle(self) -> Piece | None:
        """The piece the joint turns on: screw, pin, rod or dowel."""
        return next((p for p in self.pieces if p.role in AXLES), None)

    @property
    def engagement(self) -> tuple[float, float]:
        """Length (mm) of the axle held in each boss (a blind bore's floor and an axle ending
        inside a boss hold nothing there)."""
        axle = self.axle
        lo, hi = (-np.inf, np.inf) if axle is None else (axle.s0, axle.s1)
        return tuple(max(0.0, min(b, hi) - max(a, lo)) for a, b in (self.lower, self.upper))

    @property
    def extent(self) -> tuple[float, float]:
        """Axial range of the bosses and every piece."""
        s = [self.lower[0], self.upper[1], *(p.s0 for p in self.pieces),
             *(p.s1 for p in self.pieces)]
        return min(s), max(s)

    @property
    def reach(self) -> float:
        """Largest radius of the bosses and pieces."""
        return max(self.boss_radius, *(p.radius for p in self.pieces))


def fastener_of(kind: str) -> Fastener:
    if kind not in profiles.FASTENERS:
        raise FabricationError(f"joint kind {kind!r} is not a screw", "bad-parameters")
    return profiles.FASTENERS[kind]


def axle_diameter(kind: str, rod: Rod | None = None) -> float:
    """Diameter (mm) of the axle of a joint ``kind`` (``rod``: the grounding rod's)."""
    if kind == "rod":
        return (rod or profiles.DEFAULT_ROD).d_mm
    if kind == "printed-pin":
        return profiles.PRINTED_PIN_D_MM
    return fastener_of(kind).d_mm


def bore_radius(kind: str, printer: Printer, rod: Rod | None = None, fixed: bool = False,
                d: float | None = None) -> float:
    """Radius (mm) of the bore a joint ``kind``'s axle turns in (``fixed``: the bore the rod
    or dowel is held in, a press fit: printed holes come out small, so nominal size; ``d``
    the dowel's diameter)."""
    if kind in ("rod", "dowel"):
        d = axle_diameter(kind, rod) if kind == "rod" else float(d)
        return d / 2 if fixed else d / 2 + printer.clearance_mm + printer.hole_allowance_mm / 2
    if kind == "printed-pin":
        return profiles.PRINTED_PIN_D_MM / 2 + printer.clearance_mm + \
            printer.hole_allowance_mm / 2
    return (fastener_of(kind).hole_mm + printer.hole_allowance_mm) / 2


def min_boss_radius(kind: str, printer: Printer, rod: Rod | None = None) -> float:
    """Smallest boss radius (mm): the bore with a wall around it (and :data:`BOSS_ROOM_MM`:
    never the printer's minimum exactly, a polygon's chords are a little short), and a face
    the washers bear on."""
    wall = bore_radius(kind, printer, rod) + printer.wall_mm + BOSS_ROOM_MM
    if kind in profiles.FASTENERS:
        return max(wall, fastener_of(kind).washer_d_mm / 2)
    return wall


def outward(bar: np.ndarray, away: np.ndarray, r: float, within: float) -> float:
    """How far (mm) along ``away`` (a unit vector on the joint axis) a bar of radius ``r``
    leaving the joint point along ``bar`` has material ``within`` mm of the axis: with axial
    slope ``a`` and radial slope ``q``, ``a (within + r) / q + r q`` (at most its length);
    its section only where it leans away."""
    n = float(np.linalg.norm(bar))
    a = float(bar @ away) / n if n > 0 else 0.0
    q = np.sqrt(max(1.0 - a * a, 0.0))
    if a <= 0.0:
        return r * q
    return a * min(n, (within + r) / max(q, 1e-12)) + r * q


def blocked_sides(bars: tuple[np.ndarray, np.ndarray], w: np.ndarray,
                  faces: tuple[float, float], within: float) -> tuple[bool, bool]:
    """Whether the centre line of link j's bar (``bars[0]``, from ``E_j``) and of link j+1's
    (``bars[1]``, from ``S_{j+1}``) is still within ``within`` mm of the axis (unit ``w``)
    half a millimetre past its boss's outer face (``faces`` mm past the joint point): the
    hardware there would sit inside the bar, cutting its core (a bar leaning outwards only
    has a notch for it in its side)."""
    return (outward(bars[0], -w, 0.0, within) > faces[0] + 0.5,
            outward(bars[1], w, 0.0, within) > faces[1] + 0.5)


def cut_sides(j: Joint, bars: tuple[np.ndarray, np.ndarray], c: float, eps: float
              ) -> tuple[bool, bool]:
    """Whether the centre line of link j's bar (``bars[0]``, from ``E_j``) and of link
    j+1's (``bars[1]``, from ``S_{j+1}``) is cut at joint ``j``: by the neighbour's zone
    (:func:`parts.zone_cut`: within ``reach + c + eps`` of the axis past the split; a bar
    leaning over the pin that the split could not keep on its side) or by the room for a
    piece standing out past its own boss's outer face (a head, nut, washer or cap inside a
    bar that leaves that way)."""
    zone = j.reach + c + eps
    core = (outward(bars[0], j.w, 0.0, zone) + j.gap / 2 > j.split + 1e-9,
            j.length - outward(bars[1], -j.w, 0.0, zone) - j.gap / 2 < j.split - 1e-9)
    out = []
    for k, (face, sign) in enumerate(((j.lower[0], -1.0), (j.upper[1], 1.0))):
        past = [p.radius for p in j.pieces if (p.s0 < face - 1e-9 if k == 0 else
                                               p.s1 > face + 1e-9)]
        within = max(past, default=0.0) + SEAT_MM + eps
        out.append(bool(past) and outward(bars[k], sign * j.w, 0.0, within) >
                   sign * (face - (0.0 if k == 0 else j.length)) + 0.5)
    return core[0] or out[0], core[1] or out[1]


def split_point(length: float, lower: np.ndarray, upper: np.ndarray, w: np.ndarray,
                radii: tuple[float, float], boss: float, gap: float, eps: float
                ) -> tuple[float, tuple[float, float]]:
    """Split ``m`` of a joint and the notches left (mm): ``lower`` is link j's bar from
    ``E_j`` (vector), ``upper`` link j+1's bar from ``S_{j+1}``, ``radii`` their radii. A bar
    of radius r leaving the axis at axial slope ``a`` and radial slope ``q`` has material
    within the zone cut's radius ``boss + gap + eps`` only up to the axial reach
    ``a (boss + gap + eps + r) / q + r`` (at most its length), which must stay on its own side
    of the split; where both bars lean over the pin the split goes to the middle of the
    conflict and ``notch`` says how far each still reaches over (the zone cut notches it)."""

    zone = boss + gap + eps
    lo = outward(lower, w, radii[0], zone) + gap / 2 + eps  # link j's bar needs m >= lo
    hi = length - outward(upper, -w, radii[1], zone) - gap / 2 - eps  # link j+1's: m <= hi
    m = float(np.clip(length / 2, lo, hi) if lo <= hi else (lo + hi) / 2)
    return m, (max(0.0, lo - m), max(0.0, m - hi))


def _bosses(length: float, bars: tuple[np.ndarray, np.ndarray], w: np.ndarray,
            radii: tuple[float, float], boss: float, gap: float, eps: float, d: float,
            floors: tuple[float, float]) -> tuple[float, tuple[float, float], float, float]:
    """``(split, notch, o_lo, o_up)`` of a joint (:func:`layout`): each boss holds its axle
    over :data:`profiles.ENGAGE_TARGET` diameters past its blind ``floors`` (mm) and covers
    most of its bar's end (what stands out past the face is trimmed off)."""
    m, notch = split_point(length, bars[0], bars[1], w, radii, boss, gap, eps)
    want = profiles.ENGAGE_TARGET * d
    o_lo = max(want + floors[0] - (m - gap / 2), MIN_OUTER_MM, COVER * radii[0])
    o_up = max(want + floors[1] - (length - m - gap / 2), MIN_OUTER_MM, COVER * radii[1])
    return m, notch, o_lo, o_up


def layout(index: int, origin: np.ndarray, far: np.ndarray, axis: np.ndarray,
           bars: tuple[np.ndarray, np.ndarray], radii: tuple[float, float], boss: float,
           kind: str, printer: Printer, *, eps: float, rod: Rod | None = None,
           rod_side: int | None = None, cap: bool = True) -> Joint:
    """Layout of joint ``index`` (module docstring) between ``origin = E_j`` and ``far =
    S_{j+1}`` (mm), ``axis`` the joint axis (used when the two points coincide), ``bars``
    link j's bar from ``E_j`` and link j+1's from ``S_{j+1}`` (vectors, mm), their hex
    ``radii``, the ``boss`` radius (a screw joint one of whose bars leaves past its boss's
    outer face, or whose bosses no stock screw spans, is laid out as a ``dowel``);
    ``rod_side`` (kind ``rod``): where the rod goes on to the base (0: beyond link j's boss,
    1: beyond link j+1's). Raises :class:`FabricationError` for a boss too thin for its
    axle."""
    if kind not in (*profiles.JOINT_KINDS, "rod") or kind == "print-in-place":
        raise FabricationError(f"joint kind {kind!r} cannot be laid out", "bad-parameters")
    origin, far = np.asarray(origin, float), np.asarray(far, float)
    length = float(np.linalg.norm(far - origin))
    w = (far - origin) / length if length > 1e-9 else np.asarray(axis, float)[:3] / \
        np.linalg.norm(np.asarray(axis, float)[:3])
    if boss < min_boss_radius(kind, printer, rod) - 1e-9:
        raise FabricationError(f"joint {index}: boss radius {boss:.2f} mm is under the "
                               f"{min_boss_radius(kind, printer, rod):.2f} mm its axle needs",
                               "bad-parameters")
    d = axle_diameter(kind, rod)
    gap = fastener_of(kind).washer_t_mm if kind in profiles.FASTENERS else printer.clearance_mm
    m, notch, o_lo, o_up = _bosses(length, bars, w, radii, boss, gap, eps, d, (0.0, 0.0))
    beyond_stock = False
    if kind in profiles.FASTENERS:
        f = fastener_of(kind)
        blocked = blocked_sides(bars, w, (o_lo, o_up), f.reach_r_mm + SEAT_MM + eps)
        beyond_stock = not any(blocked) and f.screw_length(
            _screw_need(f, -o_lo, length + o_up)) is None
        if any(blocked):  # the head or nut would sit inside that bar: a dowel instead,
            # capped past the other link; where both bars run on (a joint in the middle of
            # a nearly straight rod), blind in both: nothing sits outside either boss
            kind, rod_side, cap = "dowel", blocked.index(True), not all(blocked)
            gap = printer.clearance_mm
        elif beyond_stock:  # no stock screw spans the bosses: a steel rod cut to length,
            # glued in link j's boss and capped past link j+1's, as a dowel
            kind, rod_side, gap = "dowel", 0, printer.clearance_mm
    # a dowel's blind bore leaves a floor of a wall under the fixed link's outer face; an
    # axle without a cap ends in a blind bore of the turning link, its floor past the tip
    floor = printer.wall_mm + BOSS_ROOM_MM if kind == "dowel" or not cap else 0.0
    fixed = rod_side or 0
    if kind == "dowel" or not cap:
        # the turning link's floor stands the clearance off the axle's tip
        own = floor if kind == "dowel" else 0.0
        free = 0.0 if cap else floor + printer.clearance_mm
        m, notch, o_lo, o_up = _bosses(length, bars, w, radii, boss, gap, eps, d,
                                       (own, free) if fixed == 0 else (free, own))
    s0, s3 = -o_lo, length + o_up
    screw, pieces = None, []
    c = printer.clearance_mm
    if kind in profiles.FASTENERS:
        f = fastener_of(kind)
        screw = f.screw_length(_screw_need(f, s0, s3))
        pieces = _screw_pieces(f, screw, s0, s3, m, gap)
    elif kind == "printed-pin":
        head = boss - 0.5
        # the head stands the clearance off link j's boss as the cap off link j+1's (the
        # room cut for it then ends at the boss's face, not c inside it)
        pieces = [Piece(s0 - c - profiles.PRINTED_HEAD_H_MM, s0 - c, head, "pin head",
                        printed=True),
                  Piece(s0 - c, s3 + c + profiles.PRINTED_CAP_DEPTH_MM, d / 2, "pin",
                        printed=True),
                  Piece(s3 + c, s3 + c + profiles.PRINTED_CAP_H_MM, head, "pin cap",
                        printed=True)]
    else:  # rod: a cap on the free side's end; beyond the other side it goes on to the base
        head, height = boss - 0.5, profiles.PRINTED_CAP_H_MM
        deep = profiles.PRINTED_CAP_DEPTH_MM
        a0, a3 = s0, s3  # where the axle ends in the fixed link's boss
        if kind == "dowel":  # a small cap (1 mm over the free bore, a wall around its hole
            # and over the dowel's end): it reaches past the pin's end as little as a screw's
            # nut does; the dowel ends at the blind bore's floor
            head = min(head, max(bore_radius("dowel", printer, None, False, d) + 1.0,
                                 d / 2 + GLUED_CAP_SLACK_MM + printer.wall_mm) + 0.2)
            deep = DOWEL_IN_CAP_MM
            height = deep + printer.wall_mm + DOWEL_CAP_ROOM_MM
            a0, a3 = (s0 + floor, s3) if fixed == 0 else (s0, s3 - floor)
        if not cap:  # the axle ends in the turning link's blind bore: the bore's floor, a
            # clearance past its tip, keeps that link on as the fixed link's face does from
            # the other side
            pieces = [Piece(a0, a3 - floor - c, d / 2, kind) if fixed == 0 else
                      Piece(a0 + floor + c, a3, d / 2, kind)]
        elif fixed == 0:
            pieces = [Piece(s3 + c, s3 + c + height, head, f"{kind} cap", printed=True),
                      Piece(a0, s3 + c + deep, d / 2, kind)]
        else:
            pieces = [Piece(s0 - c - height, s0 - c, head, f"{kind} cap", printed=True),
                      Piece(s0 - c - deep, a3, d / 2, kind)]
    held = kind in ("rod", "dowel")
    bores = tuple(bore_radius(kind, printer, rod, held and fixed == k, d) for k in (0, 1))
    j = Joint(index, kind, origin, w, length, m, gap, float(boss), (s0, m - gap / 2),
              (m + gap / 2, s3), bores, tuple(pieces), d, screw, notch,
              fixed if held else None, beyond_stock=beyond_stock)
    return replace(j, cut=cut_sides(j, bars, c, eps))


def _screw_need(f: Fastener, s0: float, s3: float) -> float:
    """Length (mm) of screw a joint whose bosses span ``[s0, s3]`` needs: a washer each
    side, the nut, and :data:`PROTRUDE_MM` of thread past it."""
    return s3 - s0 + 2 * f.washer_t_mm + f.nut_h_mm + PROTRUDE_MM


def _screw_pieces(f: Fastener, screw: float, s0: float, s3: float, m: float, gap: float
                  ) -> list[Piece]:
    """The hardware pieces of a screw joint whose bosses span ``[s0, s3]`` (module
    docstring), its stock ``screw`` length (mm): washer and head outside link j's face, the
    thrust washer between the bosses, washer and lock nut outside link j+1's face; the tip
    passes the nut by at least :data:`PROTRUDE_MM` (more where the stock length is longer)."""
    t = f.washer_t_mm
    under, nut0 = s0 - t, s3 + t  # under the head; the nut's inner face
    washer = f.washer_d_mm / 2
    pieces = [Piece(under - f.head_h_mm, under, f.head_d_mm / 2, "screw head"),
              Piece(under, s0, washer, "washer"),
              Piece(under, under + screw, f.d_mm / 2, "screw"),
              Piece(m - gap / 2, m + gap / 2, washer, "thrust washer"),
              Piece(s3, nut0, washer, "washer"),
              Piece(nut0, nut0 + f.nut_h_mm, f.nut_corner_r_mm, "lock nut", sides=6)]
    return pieces


def envelope(j: Joint) -> tuple[float, float]:
    """``(boss reach, hardware reach)`` (mm) of joint ``j`` for the sizing: how far its bosses
    and printed pieces (radius at most the boss radius) reach past the pin's ends, and the
    largest ``radius + reach past the ends`` of its metal pieces (a point within ``x`` of a
    segment's end is within ``x`` of the segment)."""
    lo, hi = j.lower[0], j.upper[1]
    boss = max(-lo, hi - j.length, 0.0)
    hard = 0.0
    for p in j.pieces:
        past = max(-p.s0, p.s1 - j.length, 0.0)
        if p.printed and p.role != "dowel cap":
            boss = max(boss, past)
        else:  # metal, and a dowel's cap (as narrow as a washer: no boss-wide room for it)
            hard = max(hard, p.radius + past)
    return boss, hard


def to_dict(j: Joint) -> dict:
    """The report's entry of one joint (mm; ``s`` along the axis from ``E_j``)."""
    return {"joint": j.index, "kind": j.kind, "axle_diameter_mm": j.axle_d,
            "screw_length_mm": j.screw_mm, "pin_length_mm": j.length, "split_mm": j.split,
            "gap_mm": j.gap, "boss_radius_mm": j.boss_radius,
            "bosses_mm": [list(j.lower), list(j.upper)], "bore_radius_mm": list(j.bore),
            "engagement_mm": list(j.engagement),
            "engagement_diameters": [e / j.axle_d for e in j.engagement],
            "notch_mm": list(j.notch), "bar_cut": list(j.cut), "origin_mm": j.origin.tolist(),
            "axis": j.w.tolist(),
            # rod and dowel: the link that holds the axle fixed (glued or pressed in)
            "fixed_link": j.fixed_link,
            "pieces": [{"role": p.role, "s_mm": [p.s0, p.s1], "radius_mm": p.radius,
                        "printed": p.printed, "sides": p.sides} for p in j.pieces]}


#: Steepest lean (degrees from the vertical) of a print-in-place joint's axis: its axial gaps
#: print as bridges over the lower part, which a steeper axis would need supports for, and
#: supports in a 0.4 mm gap fuse the joint.
IN_PLACE_TILT_DEG = 30.0


def in_place_refusal(axes: np.ndarray) -> str | None:
    """Why a loop with joint ``axes`` ``(6, 3)`` (directions) cannot print in place, or None:
    every axis must lean at most :data:`IN_PLACE_TILT_DEG` from one print direction."""
    d = np.asarray(axes, float)[:, :3]
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    k = np.arange(4000) + 0.5  # directions spread evenly over the sphere (Fibonacci)
    z = 1 - 2 * k / 4000
    phi = np.pi * (1 + 5**0.5) * k
    ups = np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], 1)
    lean = np.degrees(np.arccos(np.clip(np.abs(ups @ d.T), 0.0, 1.0))).max(axis=1)
    best = int(np.argmin(lean))
    if lean[best] <= IN_PLACE_TILT_DEG:
        return None
    worst = np.degrees(np.arccos(np.clip(np.abs(d @ ups[best]), 0, 1)))
    return (f"print-in-place needs every joint axis within {IN_PLACE_TILT_DEG:g} deg of the "
            f"vertical in one print orientation (its gaps print as bridges; supports in a "
            f"joint's gap fuse it), but this spatial loop's six axes lean up to "
            f"{lean[best]:.0f} deg in the best one (joints "
            + ", ".join(f"{j}: {a:.0f} deg" for j, a in enumerate(worst))
            + "); print the parts separately with --joints m3 (screws) or printed-pin")
