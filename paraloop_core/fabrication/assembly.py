"""The printed loop put together: the six links, the joints' pieces, the hardware.

:func:`build_links` makes each link of a sizing :class:`sizing.Plan` (:mod:`parts`), lying on
the print flat :func:`layout.choose_down` picks; :class:`Assembly` holds them with the joints,
the separately printed pieces (pins, caps), the metal hardware as solids (for the
verification and the pictures; not printed) and, once grounded, the base (:mod:`base`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import manifold3d as m3d
import numpy as np

from paraloop_core.algebra import dq
from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import csg, flat, keel, layout, parts, sizing
from paraloop_core.fabrication.joints import Joint
from paraloop_core.fabrication.parts import Part
from paraloop_core.fabrication.profiles import Printer

#: Polygon segments of the coarse trial parts that measure a print flat's support.
TRIAL_SEGMENTS = 8
#: Extra polygon segments tried when a boolean pinches two vertices onto one position.
RETESSELLATE = (0, 2, 6)
#: How far (mm) into its bar a link's print flat is cut where every tessellation pinched.
INTO_BAR_MM = 0.02
#: Turns (degrees) of the print flat about the bar tried last where a link still pinches.
TURN_DEG = (2.0, -2.0)


@dataclass(frozen=True)
class Hardware:
    """A metal piece (not printed): ``role`` (screw, lock nut, thrust washer, rod), the
    ``joint`` whose axis it lies on (-1: the base), ``link`` it moves with for the
    verification (a piece about a joint axis turns with either link: the lower one), its
    ``solid`` (mm, home) evaluated from the tree ``csg``, and bounding capsule ``capsule``
    ``(2, 3)`` with ``radius``."""

    role: str
    joint: int
    link: int
    solid: m3d.Manifold
    capsule: np.ndarray
    radius: float
    csg: csg.Node | None = None


@dataclass(frozen=True)
class Assembly:
    """``parts`` (links 0..5 first, then the printed pieces and the base), ``scale`` (mm per
    design unit), ``joints``, the loop's ``joint_factors`` (design units), the sizing
    ``plan``, the ``printer`` and joint ``kind``, the metal ``hardware``, and the ``slack``
    (mm) of each link's print flat (< 0: cut deeper than its bar's face by
    :func:`flat.lift`, the bar printed over support)."""

    parts: tuple[Part, ...]
    scale: float
    joints: tuple[Joint, ...]
    joint_factors: np.ndarray
    plan: sizing.Plan
    printer: Printer
    kind: str
    hardware: tuple[Hardware, ...] = ()
    slack: np.ndarray = field(default_factory=lambda: np.zeros(6))
    base: object | None = None
    #: each link's bars ``(n, 2, 3)`` (mm) and the solids joined to it (to rebuild a link)
    bars: tuple[np.ndarray, ...] = ()
    extras: dict = field(default_factory=dict)
    #: each link's keel level where it is lifted (:data:`keel.WIDE`, ``NARROW``, ``NONE``;
    #: lower where a keel did not clear the other links; none: its bar prints over support)
    keel_levels: tuple[int, ...] = (keel.WIDE,) * 6

    @property
    def links(self) -> tuple[Part, ...]:
        return self.parts[:6]


def hardware_of(joints: tuple[Joint, ...]) -> tuple[Hardware, ...]:
    """The metal pieces of every joint as :class:`Hardware` (the rod only within its joint:
    the base adds the column)."""
    out = []
    for j in joints:
        for p in j.pieces:
            if p.printed:
                continue
            node = parts.piece_solid(j, p)
            out.append(Hardware(p.role, j.index, j.index, csg.manifold(node),
                                np.stack([j.at(p.s0), j.at(p.s1)]), p.radius, node))
    return tuple(out)


def link_bars(points_mm: np.ndarray, end_bars_mm: np.ndarray | None = None) -> list[np.ndarray]:
    """Each link's bars ``(n, 2, 3)`` (mm): ``S_i E_i``; link 3's ``S_3 L``, ``R E_3`` with an
    end-effector."""
    bars = [points_mm[[2 * i, 2 * i + 1]][None] for i in range(6)]
    if end_bars_mm is not None:
        bars[3] = np.asarray(end_bars_mm, float)
    return bars


def _link(plan: sizing.Plan, i: int, all_bars: tuple[np.ndarray, ...],
          layouts: tuple[Joint, ...], printer: Printer, extras: dict,
          down: np.ndarray | None = None, keel_level: int = keel.WIDE) -> tuple[Part, float]:
    """Link ``i`` (of the links' bars ``all_bars``) and its print-flat slack: on ``down`` if
    given, else the flat :func:`layout.choose_down` picks; ``keel_level``: its keel where it
    is lifted and clears its neighbours (:func:`parts.link_part`)."""
    bars = all_bars[i]
    neighbours = tuple(
        keel.Neighbour(layouts[j].origin, layouts[j].w, nb, float(plan.radii[n]))
        for j, n, nb in ((i, (i + 1) % 6, all_bars[(i + 1) % 6][0]),
                         ((i - 1) % 6, (i - 1) % 6, all_bars[(i - 1) % 6][-1])))
    r = float(plan.radii[i])
    extra, caps = extras.get(i, (None, []))
    c = printer.clearance_mm

    def make(d: np.ndarray, lift: float | None, n: int = parts.SEGMENTS) -> Part:
        return parts.link_part(i, bars, r, d, layouts, c, extra, caps, lift, n, keel_level,
                               neighbours)

    sides = [(layouts[i], False), (layouts[(i - 1) % 6], True)]
    main = (bars[0][0], bars[-1][1])
    if down is None:
        down, slack = layout.choose_down(
            main, r, sides, printer, lambda d, lift: make(d, lift, TRIAL_SEGMENTS).manifold,
            None if extra is None else _faces(extra))
    else:
        level = float(np.max(bars.reshape(-1, 3) @ down)) + r * sizing.APOTHEM
        slack = flat.wall_slack(down, level, sides, printer.wall_mm)
    # another tessellation where a boolean pinched the solid; then the cut a hair into the
    # bar (the bar's own face on the cutting plane can leave slivers at one tessellation
    # after another; cutting it keeps every wall while the slack allows)
    tries = [(more, 0.0, down) for more in RETESSELLATE]
    # (the room to spare: beyond the full room, else beyond the least; none where lifted)
    if slack - (0.0 if slack >= 0 else flat.FLAT_SLACK) >= 2 * INTO_BAR_MM:
        tries.append((RETESSELLATE[0], -INTO_BAR_MM, down))
    # last, the flat turned a little about the bar (a coincidence of the geometry itself)
    axis = (main[1] - main[0]) / np.linalg.norm(main[1] - main[0])
    turns = dq.rotation_about_line(axis, np.zeros(3), np.radians(TURN_DEG))  # (2, 8)
    tries += [(RETESSELLATE[0], 0.0, d) for d in dq.transform_points(turns, down)]
    for more, into, d in tries:
        level = float(np.max(bars.reshape(-1, 3) @ d)) + r * sizing.APOTHEM
        s = flat.wall_slack(d, level, sides, printer.wall_mm)
        part = make(d, flat.lift(s) + into, parts.SEGMENTS + more)
        if not parts.pinched(part.manifold):
            return part, float(s)
    raise FabricationError(f"link_{i} comes out pinched (two vertices at one position) at "
                           "every tessellation and flat tried", "not-watertight")



def _faces(solid: m3d.Manifold) -> np.ndarray:
    """``(2, 3)``: the two directions across an end-effector solid's thinnest extent (a panel
    laid on its face)."""
    v = np.asarray(solid.to_mesh().vert_properties[:, :3], float)
    normal = np.linalg.svd(v - v.mean(axis=0), full_matrices=False)[2][-1]
    return np.stack([normal, -normal])


def build_links(plan: sizing.Plan, bars: list[np.ndarray], printer: Printer,
                extras: dict, keel_levels: tuple[int, ...] = (keel.WIDE,) * 6
                ) -> tuple[tuple[Part, ...], np.ndarray]:
    """The six link parts of ``plan`` (their ``bars`` in mm, :func:`link_bars`) and their
    print-flat slack (mm); ``extras``: per link a solid joined to it (mm) with its capsules
    (P, a carved body); such links are not cut flat; ``keel_levels`` each link's keel."""
    built = [_link(plan, i, tuple(bars), plan.layouts, printer, extras,
                   keel_level=keel_levels[i]) for i in range(6)]
    return tuple(p for p, _ in built), np.array([s for _, s in built])


def assemble(plan: sizing.Plan, points: np.ndarray, joint_factors: np.ndarray,
             printer: Printer, kind: str, *, end_bars: np.ndarray | None = None,
             extras: dict | None = None, keel_levels: tuple[int, ...] = (keel.WIDE,) * 6
             ) -> Assembly:
    """:func:`build_links` on the polyline ``points`` ``(12, 3)`` (design units; ``end_bars``
    link 3's bars with an end-effector, design units) plus the printed pieces and the
    hardware of the joints."""
    k = plan.scale
    bars = link_bars(np.asarray(points, float) * k,
                     None if end_bars is None else np.asarray(end_bars, float) * k)
    links, slack = build_links(plan, bars, printer, extras or {}, keel_levels)
    for p in links:
        parts.check_solid(p.manifold, p.name)
    pieces = parts.piece_parts(plan.layouts)
    return Assembly((*links, *pieces), plan.scale, plan.layouts,
                    np.asarray(joint_factors, float), plan, printer, kind,
                    hardware_of(plan.layouts), slack, None, tuple(bars), dict(extras or {}),
                    tuple(keel_levels))


def relay(asm: Assembly, j: int, joint: Joint) -> Assembly:
    """``asm`` with joint ``j`` laid out anew (``joint``): its two links rebuilt (on their
    print flats, chosen again where the new bores would break the walls there), its pieces and
    hardware replaced."""
    layouts = tuple(joint if i == j else x for i, x in enumerate(asm.joints))
    new_parts = list(asm.parts[:6])
    slack = asm.slack.copy()
    for i in (j, (j + 1) % 6):
        # the link's print flat stays where it still leaves every bore its wall
        keep = asm.parts[i].down
        r = float(asm.plan.radii[i])
        level = float(np.max(asm.bars[i].reshape(-1, 3) @ keep)) + r * sizing.APOTHEM
        sides = [(layouts[i], False), (layouts[(i - 1) % 6], True)]
        down = keep if flat.lies_flat(flat.wall_slack(keep, level, sides,
                                                       asm.printer.wall_mm)) else None
        new_parts[i], slack[i] = _link(asm.plan, i, asm.bars, layouts, asm.printer,
                                       asm.extras, down, asm.keel_levels[i])
        parts.check_solid(new_parts[i].manifold, new_parts[i].name)
    others = [p for p in asm.parts[6:] if not (p.role in ("pin", "cap") and p.joint[0] == j)]
    pieces = [p for p in parts.piece_parts((joint,))]
    hardware = tuple(h for h in asm.hardware if h.joint != j) + hardware_of((joint,))
    plan = replace(asm.plan, layouts=layouts)
    return replace(asm, parts=(*new_parts, *others, *pieces), joints=layouts, plan=plan,
                   hardware=hardware, slack=slack)


def bar_vectors(asm: Assembly, j: int) -> tuple[np.ndarray, np.ndarray]:
    """Link j's bar from ``E_j`` and link j+1's from ``S_{j+1}`` (vectors, mm)."""
    lo, up = asm.bars[j], asm.bars[(j + 1) % 6]
    return lo[-1][0] - lo[-1][1], up[0][1] - up[0][0]


def with_parts(asm: Assembly, extra: tuple[Part, ...], hardware: tuple[Hardware, ...] = (),
               base: object | None = None) -> Assembly:
    """``asm`` with more parts (the base) and hardware (the column rod)."""
    return replace(asm, parts=asm.parts + extra, hardware=asm.hardware + hardware,
                   base=base if base is not None else asm.base)
