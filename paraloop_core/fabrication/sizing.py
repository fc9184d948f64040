"""Size and thickness of the parts: the strongest links the certificate allows.

The room between the links is the certificate's (:mod:`rows`: one capsule per bar, per
joint's bosses and per joint's hardware, and a linear programme in the twelve radii that keeps
a gap in every certified row). Here the programme's bounds are set: the largest thinnest bar,
then the largest sum, every bar at least :data:`WIDTH_MM` wide and at most :data:`LW_MAX` times
as long, bosses :data:`rows.BOSS_PER_BAR` times the bar they hold and wide enough for their
axle (any joint may become the grounded joint on the rod). The gaps are
:func:`stiffness.required_gaps` of the predicted deflections, so the LP is repeated until the
radii, the joint layouts (how far bosses and hardware reach past the pins) and the
deflections agree.

:func:`plan` picks the size: the largest at which the predicted parts fit the printer's bed
(or the caller's size) and the programme is feasible; the built parts are measured again
(:mod:`printable`).
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from dataclasses import dataclass, field, replace

import numpy as np

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import bed, flat, joints, rows, stiffness
from paraloop_core.fabrication.profiles import Material, Printer, Rod
from paraloop_core.fabrication.rows import BOSS_PER_BAR, Bounds, bounds_of, envelopes, radii

#: Bars at least this wide across flats (mm): the floor, and the width aimed for. The floor
#: is a maker's 6 mm plus twice a printer's 0.2 mm tolerance: a bar sized at 6.00 mm prints
#: (and measures) under it.
WIDTH_MM, WIDTH_AIM_MM = 6.4, 7.0
#: Bar length per width across flats: the ceiling (30 less a margin, as the floor), and the
#: ratio aimed for.
LW_MAX, LW_AIM = 28.0, 25.0
#: Thickest bar (corner radius, mm) as a fraction of the size, within [lo, hi] mm: thicker
#: only adds mass (and motor torque) to a desk model.
BAR_CAP = (0.028, 4.5, 8.0)
#: Thickest bar (corner radius, mm) grown past :data:`BAR_CAP` where its print flat would
#: otherwise cut into a bore (:func:`flat_radii`).
FLAT_CAP_MM = 12.0
#: Room (mm) the grown bars' flats keep beyond the bores' walls: the built parts' layouts
#: differ a little from the programme's (boss lengths follow the radii), and a flat at its
#: limit would leave the cut to the last tessellation.
FLAT_ROOM_MM = 0.4
#: Rounds of growing bars for their print flats (the layouts follow the radii).
FLAT_ROUNDS = 4
#: Gaps the programme keeps, per required gap, when it can (the verification then proves the
#: required gap with room to spare, not at its limit).
GAP_MARGIN = 1.1
#: Thickest bar per the radius its deflection bound needs (keeps the parts' mass, and so the
#: torque the bound was computed for, in check).
THICKER = 1.35
#: Bounds (mm) on each link's predicted deflection tried by :func:`at_scale`, stiffest first.
DEFLECTION_STEPS = (0.1, 0.15, 0.25, 0.4, 0.6, 0.9)
#: What the sizing reaches, best first: the aims (bars 7 mm wide, 25 times as long, gaps 3 x
#: the deflections and 10 % more), the floors (6.4 mm, 28, 3 x), the least gap (1 mm between
#: every two links, however they bend), thin (bars only as thick as their bores' walls need).
LEVELS = ("aims", "floors", "least gap", "thin bars")
#: Smallest size (mm) the search goes down to.
MIN_SIZE_MM = 100.0
#: Sizes (mm) tried below the bed's limit, as factors, when the programme is infeasible there;
#: sizes between one whose parts are too large and a smaller one they may fit at: BETWEEN - 1.
SHRINK, BETWEEN = 0.9, 4
#: Shares of the room between a bar's floor and its cap that :func:`_radii_settle` allows in
#: turn where thicker bars' bosses and hardware take the room they were given.
CAP_SHARES = (0.5, 0.2, 0.0)
#: Hex bars per corner radius: across flats (width) and the flat's distance from the axis.
FLATS = np.sqrt(3.0)
APOTHEM = np.sqrt(3.0) / 2.0


@dataclass(frozen=True)
class Plan:
    """The sizing: ``size_mm`` (longest side of the polyline), ``scale`` (mm per unit), bar
    corner ``radii`` ``(6,)`` and ``boss`` radii ``(6,)`` (mm), the joint ``layouts``, the
    ``deflection`` estimate, the required ``gaps`` ``(6, 6)`` (the programme kept
    :data:`GAP_MARGIN` more at level 0), the motor ``torque_nm`` bound used, the
    :data:`LEVELS` ``level`` reached, the joint ``kind`` asked for (a screw joint whose bar
    runs on past its boss is laid out as a dowel, :func:`joints.layout`) and ``notes``."""

    size_mm: float
    scale: float
    radii: np.ndarray
    boss: np.ndarray
    layouts: tuple[joints.Joint, ...]
    deflection: stiffness.Deflection
    gaps: np.ndarray
    torque_nm: float
    level: int
    #: the resting (grounded) link the torque was planned for (-1: the worst of all)
    rest: int = -1
    kind: str = "m3"
    notes: tuple[str, ...] = field(default=())

    @property
    def aims_met(self) -> bool:
        return self.level == 0


def bar_cap(size_mm: float) -> float:
    """Thickest bar corner radius (mm) at ``size_mm`` (:data:`BAR_CAP`)."""
    f, lo, hi = BAR_CAP
    return float(np.clip(f * size_mm, lo, hi))


def min_radii(b: Bounds, k: float, printer: Printer, kind: str, level: int) -> np.ndarray:
    """Thinnest bar corner radius ``(6,)`` (mm) at ``k`` mm per unit at a :data:`LEVELS`
    level: the width and length per width (the aims, the floors, or none at the last level)
    and a wall between the bore and the bar's flat underside (the part is printed on that
    flat: its bosses are cut to it; :func:`flat_radii` adds the tilt of the axes)."""
    flat_r = (joints.bore_radius(kind, printer) + printer.wall_mm) / APOTHEM
    if level >= 3:
        return np.full(6, flat_r)
    width, lw = (WIDTH_AIM_MM, LW_AIM) if level == 0 else (WIDTH_MM, LW_MAX)
    return np.maximum.reduce([np.full(6, width / FLATS), b.bar_lengths * k / (lw * FLATS),
                              np.full(6, flat_r)])


def min_boss(printer: Printer, kind: str, rod: Rod) -> float:
    """Smallest boss radius (mm) of every joint: its own axle, or the rod if it becomes the
    grounded joint."""
    return max(joints.min_boss_radius(kind, printer), joints.min_boss_radius("rod", printer, rod))


def _layouts(b: Bounds, k: float, r: np.ndarray, boss: np.ndarray, kind: str,
             printer: Printer, eps: float) -> tuple[joints.Joint, ...]:
    pts = b.points * k
    out = []
    for j in range(6):
        e, s = pts[2 * j + 1], pts[(2 * j + 2) % 12]
        bars = (pts[2 * j] - e, pts[(2 * j + 3) % 12] - s)
        out.append(joints.layout(j, e, s, b.axes[j, :3], bars, (r[j], r[(j + 1) % 6]),
                                 boss[j], kind, printer, eps=eps))
    return tuple(out)


def at_scale(real, b: Bounds, k: float, printer: Printer, material: Material, kind: str,
             rod: Rod, eps: float, matrix: np.ndarray, level: int = 0, rest: int | None = None,
             shares: tuple[float, ...] = (1.0,)) -> Plan | None:
    """The :class:`Plan` at ``k`` mm per unit at a :data:`LEVELS` level, or None when no
    radii meet the rows there.

    The deflections couple the radii to the gaps (thicker bars bend less but leave less
    room), so the programme runs with a bound ``delta`` on every link's predicted deflection
    (:data:`DEFLECTION_STEPS`, stiffest first): each bar at least the radius that keeps it
    (:func:`stiffness.radius_for`) under the motor torque of bars up to :data:`THICKER` times
    that radius (their upper bound in the programme), every gap at least
    ``max(1 mm, 3 x 2 delta)`` (levels 0 and 1; 2 and 3 the least gap). The first feasible
    one is kept."""
    size = k * b.extent
    rcap, bmin = bar_cap(size), min_boss(printer, kind, rod)
    lengths = b.bar_lengths * k
    e, rho = material.modulus_gpa, material.density_g_cm3
    margin = GAP_MARGIN if level == 0 else 1.0
    floor = min_radii(b, k, printer, kind, level)
    if np.any(floor > rcap + 1e-9) or level < 2 and not _floors_fit(b, k, floor, printer,
                                                                   kind, eps, bmin):
        return None
    if level >= 2:
        top = np.full(6, rcap)
        plan = _settle(real, b, k, printer, material, kind, eps, floor, top, bmin,
                       np.full((6, 6), stiffness.MIN_GAP_MM), matrix, rest, level < 3, shares)
        # the gaps required are those kept: the least gap (the warning says the deflections
        # may be larger); the verification and the rod's clearance check these
        return None if plan is None else replace(
            plan, level=level, gaps=np.full((6, 6), stiffness.MIN_GAP_MM))
    for delta in DEFLECTION_STEPS:
        # the torque of bars up to THICKER x the radius they need, which needs the torque:
        # a few rounds of the fixed point (monotone: heavier parts need thicker bars)
        rmin = floor
        for _ in range(4):
            top = np.minimum(rcap, THICKER * rmin)
            tq = stiffness.torque_bound(real, k, top, BOSS_PER_BAR * top, rho, matrix, rest)
            need = np.maximum(floor, stiffness.radius_for(delta, lengths, e, rho, tq))
            if np.all(need <= rmin + 1e-9):
                break
            rmin = need
        if np.any(rmin > rcap) or np.any(need > rmin + 1e-9):
            continue
        gaps = stiffness.required_gaps(np.full(6, delta)) * margin
        plan = _settle(real, b, k, printer, material, kind, eps, rmin, top, bmin, gaps, matrix,
                       rest, True, shares)
        if plan is not None:
            return replace(plan, level=level)
    return None


def _floors_fit(b: Bounds, k: float, floor: np.ndarray, printer: Printer, kind: str,
                eps: float, bmin: float) -> bool:
    """Whether bars at their ``floor`` radii, the least bosses and gaps meet every row:
    each deflection bound of :func:`at_scale` asks more (thicker bars, bosses reaching
    farther, larger gaps), so where this fails their programmes are skipped."""
    boss = rows.least_bosses(floor, bmin)
    try:
        env = envelopes(_layouts(b, k, floor, boss, kind, printer, eps))
    except FabricationError:
        return False
    return radii(b, k, floor, floor, bmin, env, np.full((6, 6), stiffness.MIN_GAP_MM)) is not None


def _settle(real, b: Bounds, k: float, printer: Printer, material: Material, kind: str,
            eps: float, rmin: np.ndarray, rcap: np.ndarray, bmin: float, gaps: np.ndarray,
            matrix: np.ndarray, rest: int | None, lay_flat: bool,
            shares: tuple[float, ...] = (1.0,)) -> Plan | None:
    """:func:`_radii_settle`; with ``lay_flat``, bars whose print flat would cut into a bore
    (:func:`flat_radii`) are then made that much thicker (up to :data:`FLAT_CAP_MM`) where
    the programme still holds and the heavier parts bend no more than ``gaps`` allows: all
    such bars at once, else one at a time; the others stay thinner (printed uncut, on
    support)."""
    plan = _radii_settle(real, b, k, printer, material, kind, eps, rmin, rcap, bmin, gaps,
                         matrix, rest, shares)

    def notches(p: Plan) -> np.ndarray:
        return np.array([j.notch for j in p.layouts])

    def thicker(grow: np.ndarray, need: np.ndarray) -> tuple[Plan | None, np.ndarray]:
        # kept only if no bar bends more than the gaps allow and no bar leaning over a pin
        # is notched deeper by the grown bosses (a notch can cut a thin bar through)
        lo = np.where(grow, np.maximum(rmin, need), rmin)
        p = _radii_settle(real, b, k, printer, material, kind, eps, lo, np.maximum(rcap, lo),
                          bmin, gaps, matrix, rest, shares)
        ok = p is not None and np.all(p.gaps <= gaps + 1e-9) and np.all(
            notches(p) <= notches(plan) + 1e-9)
        return (p, lo) if ok else (None, lo)

    for _ in range(FLAT_ROUNDS if lay_flat else 0):
        if plan is None:
            break
        need = flat_radii(b, k, plan.layouts, printer.wall_mm + FLAT_ROOM_MM)
        short = (flat_radii(b, k, plan.layouts, printer.wall_mm) > plan.radii) & (
            need <= max(float(np.max(rcap)), FLAT_CAP_MM))
        tries = [short] + ([np.arange(6) == i for i in np.argsort(plan.radii - need)
                            if short[i]] if short.sum() > 1 else [])
        for grow in tries if np.any(short) else []:
            better, lo = thicker(grow, need)
            if better is not None:
                plan, rmin = better, lo
                break
        else:
            break
    return plan


def flat_radii(b: Bounds, k: float, layouts: tuple[joints.Joint, ...], wall: float
               ) -> np.ndarray:
    """Least bar corner radius ``(6,)`` (mm) at ``k`` mm per unit at which each link's print
    flat (:mod:`flat`, best turn) keeps every wall of its joints' ``layouts``."""
    pts = b.points * k
    return np.array([flat.least_depth((pts[2 * i], pts[2 * i + 1]),
                                      [(layouts[i], False), (layouts[(i - 1) % 6], True)],
                                      wall) for i in range(6)]) / APOTHEM


def _radii_settle(real, b: Bounds, k: float, printer: Printer, material: Material, kind: str,
                  eps: float, rmin: np.ndarray, rcap: np.ndarray, bmin: float, gaps: np.ndarray,
                  matrix: np.ndarray, rest: int | None, shares: tuple[float, ...] = (1.0,)
                  ) -> Plan | None:
    """Radii for fixed ``gaps``, repeated until the joint layouts they imply (how far the
    bosses and hardware reach past the pins) are those the programme assumed. Thicker bars
    grow their bosses and the hardware's reach, which can take the room the bars were given:
    then the bars' cap is lowered towards their floor (``shares`` of the room between them,
    :data:`CAP_SHARES` in :func:`plan`'s second pass) and the fixed point tried again."""
    cap = np.broadcast_to(np.asarray(rcap, float), (6,))
    for share in shares:
        top = rmin + share * np.maximum(cap - rmin, 0.0)
        plan = _fixed_point(real, b, k, printer, material, kind, eps, rmin, top, bmin, gaps,
                            matrix, rest)
        if plan is not None:
            return plan
    return None


def _fixed_point(real, b: Bounds, k: float, printer: Printer, material: Material, kind: str,
                 eps: float, rmin: np.ndarray, rcap: np.ndarray, bmin: float,
                 gaps: np.ndarray, matrix: np.ndarray, rest: int | None) -> Plan | None:
    r = rmin
    boss = rows.least_bosses(r, bmin)
    env = np.zeros((6, 2))
    for _ in range(4):
        try:
            env = np.maximum(env, envelopes(_layouts(b, k, r, boss, kind, printer, eps)))
            sol = radii(b, k, rmin, rcap, bmin, env, gaps)
            if sol is None:
                return None
            r, boss = sol
            lay = _layouts(b, k, r, boss, kind, printer, eps)
        except FabricationError:
            return None
        if np.all(envelopes(lay) <= env + 1e-9):
            tq = stiffness.torque_bound(real, k, r, boss, material.density_g_cm3, matrix, rest)
            d = stiffness.deflections(b.bar_lengths * k, r, np.ones(6), material.modulus_gpa,
                                      material.density_g_cm3, tq)
            return Plan(k * b.extent, k, r, boss, lay, d, stiffness.required_gaps(d.total),
                        tq, 0, -1 if rest is None else rest, kind)
    return None


def plan(real, printer: Printer, material: Material, kind: str, rod: Rod, *,
         size_mm: float | None = None, eps: float = 0.05, fit=None, ee=None) -> Plan:
    """The :class:`Plan` (module docstring) of a realization: the first :data:`LEVELS` level
    met at some size, at the largest such size whose predicted parts fit the bed
    (``fit(plan) -> factor``: by how much the parts may still grow, <= 1 when they do not
    fit), shrinking by :data:`SHRINK` down to :data:`MIN_SIZE_MM`; at ``size_mm`` if given.
    Raises :class:`FabricationError` when no level is met at any size tried. ``ee``: the
    end-effector realization whose rows bound link 3's P and bars too."""
    b = bounds_of(real, ee)
    matrix = stiffness.torque_matrix(real)
    rest = stiffness.easiest_rest(real, matrix)
    if size_mm is None and not _any_size(real, b, printer, material, kind, rod, eps, matrix,
                                         rest):
        raise _no_room(b, printer, kind, None)
    # each level first with the bars as thick as the rows allow at every size, then letting
    # them give room to the bosses and hardware they would grow (:func:`_radii_settle`)
    for level, shares in itertools.product(range(len(LEVELS)), ((1.0,), CAP_SHARES)):
        if size_mm is not None:
            p = at_scale(real, b, size_mm / b.extent, printer, material, kind, rod, eps, matrix,
                         level, rest, shares)
            if p is not None:
                return p
            continue
        k, between = bed.bed_scale(b.points, printer), []
        while k * b.extent >= MIN_SIZE_MM:
            p = at_scale(real, b, k, printer, material, kind, rod, eps, matrix, level, rest,
                         shares)
            grow = 0.0 if p is None else fit(p) if fit is not None else 1.0
            if grow >= 1.0:
                return p
            if p is not None:  # too large: down to where it may fit, else the sizes between
                # (stock hardware makes the room uneven: 62215 has radii at 412 - 448 mm only)
                to = k * max(min(grow, 0.99), 0.5)
                between, k = [to * (k / to) ** (j / BETWEEN) for j in range(1, BETWEEN)], to
            else:
                k = between.pop(0) if between else k * SHRINK
    raise _no_room(b, printer, kind, size_mm)


def _sizes(b: Bounds, printer: Printer) -> Iterator[float]:
    """Scales (mm per unit): the bed's down to :data:`MIN_SIZE_MM` by :data:`SHRINK`."""
    k = bed.bed_scale(b.points, printer)
    while k * b.extent >= MIN_SIZE_MM:
        yield k
        k *= SHRINK


def _any_size(real, b: Bounds, printer: Printer, material: Material, kind: str, rod: Rod,
              eps: float, matrix: np.ndarray, rest: int | None) -> bool:
    """Whether the loosest level (thin bars: least floors, least gaps) with every cap share
    has radii at some size of :func:`_sizes`: every other level asks more at each size, so
    when it has none, no level has (a quick, true refusal)."""
    last = len(LEVELS) - 1
    return any(at_scale(real, b, k, printer, material, kind, rod, eps, matrix, last, rest,
                        (1.0, *CAP_SHARES)) is not None for k in _sizes(b, printer))


class NoRoomError(FabricationError):
    """The joints' bosses and hardware do not fit the room a realization's certificate leaves
    at any size tried (a larger print may have room: :mod:`remedy`)."""


def _no_room(b: Bounds, printer: Printer, kind: str, size_mm: float | None
             ) -> NoRoomError:
    where = f"at {size_mm:.0f} mm" if size_mm is not None else \
        f"at every size tried from {bed.bed_scale(b.points, printer) * b.extent:.0f} mm " \
        f"down to {MIN_SIZE_MM:g} mm ({100 * (1 - SHRINK):.0f} % apart)"
    return NoRoomError(
        f"{where} the joints' bosses and hardware ({kind}) and bars do not fit in the room "
        "this realization's certificate leaves between the links", "bad-parameters")


def shortfall(plan: Plan) -> np.ndarray:
    """Each bar's ``(6,)`` larger of :data:`WIDTH_MM` / width and length per width /
    :data:`LW_MAX` (> 1: short of the floors)."""
    width = plan.radii * FLATS
    return np.maximum(WIDTH_MM / width, plan.deflection.lengths / width / LW_MAX)


def limiting(plan: Plan, b: Bounds) -> dict:
    """The certified row that holds the weakest bar back (:func:`shortfall`, the thinnest
    among equals): of its rows, the one with the least room left at the plan's radii,
    bosses, joint reaches and gaps; and what that bar reaches."""
    env, k = envelopes(plan.layouts), plan.scale
    thin = int(np.lexsort((plan.radii, -np.round(shortfall(plan), 9)))[0])
    best = None
    for (e1, e2, la, lb), low in zip(b.rows, b.lower, strict=True):
        if thin * 2 not in (e1, e2):
            continue
        use = 0.0
        for e in (int(e1), int(e2)):
            use += plan.radii[e // 2] if e % 2 == 0 else plan.boss[e // 2] + env[e // 2, 0]
        room = k * low - use - plan.gaps[la, lb]
        if best is None or room < best[0]:
            best = (room, int(la), int(lb), k * low, None)
    # the bars of two links on one joint pass each other as it turns (often the tightest)
    for i in range(6):
        j = (i + 1) % 6
        if thin in (i, j) and np.isfinite(b.joint_lower[i]):
            room = k * b.joint_lower[i] - plan.radii[i] - plan.radii[j] - plan.gaps[i, j]
            if best is None or room < best[0]:
                best = (room, i, j, k * b.joint_lower[i], i)
    if best is None:
        return {}
    width = float(plan.radii[thin] * FLATS)
    return {"links": [best[1], best[2]], "thinnest_bar_link": thin,
            "certified_distance_mm": best[3], "room_left_mm": best[0], "joint": best[4],
            "bar_width_mm": width,
            "length_per_width": float(plan.deflection.lengths[thin] / width),
            "meaning": "the pair of links whose certified distance over the cycle, less the "
                       "other's bar or joint and the gap they keep, limits the weakest bar "
                       f"(thinnest_bar_link: the furthest from {WIDTH_MM:g} mm wide and "
                       f"{LW_MAX:g} times as long as wide; its width and length per width "
                       "are what this realization reaches; joint: the two links' common "
                       "joint, where their bars pass each other as it turns; null: links "
                       "without a common joint)"}


def to_dict(plan: Plan, printer: Printer, b: Bounds | None = None) -> dict:
    """The report's ``sizing`` entry (with ``b``: the limiting pair, :func:`limiting`)."""
    return {"limiting_pair": limiting(plan, b) if b is not None else {},
            "size_mm": plan.size_mm, "scale_mm_per_unit": plan.scale,
            "bar_radius_mm": plan.radii.tolist(),
            "bar_width_mm": (plan.radii * FLATS).tolist(), "boss_radius_mm": plan.boss.tolist(),
            "aims_met": plan.aims_met, "level": LEVELS[plan.level],
            "motor_torque_bound_nm": plan.torque_nm,
            "required_gap_mm": plan.gaps.tolist(), "printer": printer.name,
            "bed_mm": list(printer.bed_mm), "wall_mm": printer.wall_mm,
            "clearance_mm": printer.clearance_mm,
            "method": "largest size whose parts fit the bed; bar (hexagon corner) and boss radii "
                      "from one linear programme over the certified pair bounds (largest "
                      "thinnest bar, then largest bars), every gap between links without a "
                      f"common joint at least max({stiffness.MIN_GAP_MM:g} mm, "
                      f"{stiffness.GAP_PER_DEFLECTION:g} x their predicted deflections)"}


def level_warnings(plan: Plan) -> list[str]:
    """What the sizing could not reach, in words (:data:`LEVELS`)."""
    if plan.level == 2:
        return ["the certificate leaves room for the gaps of 1 mm between the links, not for "
                "three times their predicted deflection: handle it gently near its tightest "
                "pose (report: sizing.limiting_pair)"]
    if plan.level == 3:
        width = plan.radii * FLATS
        lw = float(np.max(plan.deflection.lengths / width))
        return [f"bars down to {width.min():.2f} mm wide and up to {lw:.0f} times as long as "
                f"wide, beyond the {WIDTH_MM:g} mm and {LW_MAX:g} a printed bar "
                "should keep: the best this realization's certificate allows; handle it gently "
                "(report: sizing.limiting_pair names the pair that limits it)"]
    return []
