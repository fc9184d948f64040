"""Joint layouts (:mod:`fabrication.joints`): engagement, stock screws and their hardware
outside the bosses, printed pins,
the grounding rod, the split between two bars, what bounds a joint, print-in-place refusals."""

from __future__ import annotations

import re

import fab_fixtures as F
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import csg, guide, joints, parts, profiles
from paraloop_core.linkage import loops

GENERIC = profiles.PRINTERS["generic"]
Z = np.array([0.0, 0.0, 1.0])


def pin(kind: str, length: float = 10.0, boss: float = 6.0, rod_side: int | None = None,
        printer: profiles.Printer = GENERIC) -> joints.Joint:
    """A pin along z from the origin, the two bars leaving it at right angles."""
    return joints.layout(0, np.zeros(3), length * Z, Z, (np.array([-40.0, 0, 0]),
                                                         np.array([0, 40.0, 0])),
                         (4.0, 4.0), boss, kind, printer, eps=0.05,
                         rod=profiles.DEFAULT_ROD if kind == "rod" else None,
                         rod_side=rod_side)


def held(j: joints.Joint) -> tuple[float, float]:
    """Length (mm) of the axle each boss holds: the boss ranges, less what of them the axle
    piece does not reach (a dowel's blind floor)."""
    (axle,) = [p for p in j.pieces if p.role in ("screw", "pin", "rod", "dowel")]
    return (min(j.lower[1], axle.s1) - max(j.lower[0], axle.s0),
            min(j.upper[1], axle.s1) - max(j.upper[0], axle.s0))


KINDS = [("m3", None), ("m4", None), ("printed-pin", None), ("rod", 0), ("rod", 1)]


@pytest.mark.parametrize(("kind", "side"), KINDS)
@pytest.mark.parametrize("length", [0.0, 2.0, 10.0, 30.0])
def test_each_boss_holds_two_diameters(kind, side, length):
    j = pin(kind, length, boss=7.0, rod_side=side)
    d = {"m3": 3.0, "m4": 4.0, "printed-pin": profiles.PRINTED_PIN_D_MM,
         "rod": profiles.DEFAULT_ROD.d_mm}[kind]
    assert j.axle_d == d
    assert min(held(j)) >= profiles.ENGAGE_TARGET * d - 1e-9 >= profiles.ENGAGE_MIN * d
    assert held(j) == pytest.approx(j.engagement)
    # the bosses meet at the split, across the gap, and cover the pin
    assert j.upper[0] - j.lower[1] == pytest.approx(j.gap)
    assert j.lower[0] <= 0.0 and j.upper[1] >= length
    assert j.lower[1] < j.split < j.upper[0]


@pytest.mark.parametrize("kind", ["m3", "m4", "printed-pin"])
def test_every_joint_of_the_sized_loops_is_engaged(kind):
    for j in F.plan(kind).layouts:
        assert min(held(j)) >= profiles.ENGAGE_TARGET * j.axle_d - 1e-9
        assert j.kind in (kind, "dowel")
        assert j.boss_radius >= joints.min_boss_radius(kind, GENERIC)


@pytest.mark.parametrize("kind", ["m2", "m3", "m4"])
@pytest.mark.parametrize("side", [0, 1])
def test_a_bar_leaving_past_a_boss_gets_a_dowel_in_a_blind_bore(kind, side):
    """Link j's (side 0) or link j+1's bar leaves along the axis past its boss's outer face:
    a screw's head or nut would sit inside that bar. The joint becomes a dowel of the screw's
    diameter held in a blind bore of that link (a wall-thick floor, nothing cut beyond it:
    the bar goes on whole), turning in the other link, capped there; both hold 2 diameters."""
    f = profiles.FASTENERS[kind]
    along = np.array([3.0, 0.0, 80.0]) * (1 if side else -1)
    bars = (along, np.array([0, 40.0, 0])) if side == 0 else (np.array([-40.0, 0, 0]), along)
    j = joints.layout(0, np.zeros(3), 12 * Z, Z, bars, (5.0, 5.0), 7.0, kind, GENERIC,
                      eps=0.05)
    assert (j.kind, j.rod_side, j.axle_d, j.screw_mm) == ("dowel", side, f.d_mm, None)
    (axle,) = [p for p in j.pieces if p.role == "dowel"]
    (cap,) = [p for p in j.pieces if p.printed]
    assert cap.role == "dowel cap" and cap.radius <= f.reach_r_mm + 0.6
    boss = j.upper if side else j.lower
    floor = boss[1] - axle.s1 if side else axle.s0 - boss[0]
    assert floor >= GENERIC.wall_mm
    assert min(held(j)) >= profiles.ENGAGE_TARGET * f.d_mm - 1e-9
    assert j.bore[side] == pytest.approx(f.d_mm / 2)  # glued / pressed
    assert j.bore[1 - side] > f.d_mm / 2 + GENERIC.clearance_mm - 1e-9  # turns
    # the cap sits past the other link's outer face, the dowel reaches into it
    if side == 0:
        assert cap.s0 > j.upper[1] and axle.s1 > cap.s0 + 2.0
    else:
        assert cap.s1 < j.lower[0] and axle.s0 < cap.s1 - 2.0
    # the fixed link's hole ends at the floor: nothing past its outer face
    hole = csg.manifold(parts.holes(j, bool(side), 30.0)).bounding_box()
    if side == 0:
        assert hole[2] == pytest.approx(axle.s0)
    else:
        assert hole[5] == pytest.approx(axle.s1)
    # crossing bars (the usual case) keep the screw
    assert pin(kind, 12.0).kind == kind


@pytest.mark.parametrize("side", [0, 1])
def test_a_rod_without_a_cap_ends_in_a_blind_bore(side):
    """A grounding rod laid out without its cap (every capped one cut a bar or left a link in
    pieces): it ends a clearance short of a floor a wall thick in the turning link's bore, so
    that link cannot slide off its end; it still holds 2 diameters in each boss; the turning
    link's hole stops at the floor, the grounded link's runs on to the base."""
    j = joints.layout(0, np.zeros(3), 10 * Z, Z, (np.array([-40.0, 0, 0]),
                                                   np.array([0, 40.0, 0])), (4.0, 4.0), 6.0,
                      "rod", GENERIC, eps=0.05, rod=profiles.DEFAULT_ROD, rod_side=side,
                      cap=False)
    assert not any(p.printed for p in j.pieces)
    rod = j.axle
    d = profiles.DEFAULT_ROD.d_mm
    assert min(held(j)) >= profiles.ENGAGE_TARGET * d - 1e-9
    turning = 1 - side
    tip, face = (rod.s1, j.upper[1]) if turning == 1 else (rod.s0, j.lower[0])
    assert abs(face - tip) >= GENERIC.wall_mm + GENERIC.clearance_mm - 1e-9
    hole = csg.manifold(parts.holes(j, bool(turning), 30.0)).bounding_box()
    end = hole[5] if turning == 1 else hole[2]
    assert end == pytest.approx(tip + (GENERIC.clearance_mm if turning == 1 else
                                       -GENERIC.clearance_mm))
    assert abs(face - end) >= GENERIC.wall_mm - 1e-9  # the floor
    through = csg.manifold(parts.holes(j, bool(side), 30.0)).bounding_box()
    assert through[2] < j.lower[0] - 10 and through[5] > j.upper[1] + 10


def test_a_joint_in_a_straight_rod_is_a_dowel_in_two_blind_bores():
    """Both bars leave along the axis past their bosses' outer faces (a joint in the middle of
    a nearly straight rod): a head and a nut would sit inside both bars. The joint is a dowel
    glued in link j's blind bore and turning in link j+1's, whose floor stands a clearance
    past its tip (it keeps link j+1 on): nothing outside either boss, no bar cut, 2 diameters
    held in each boss, the guide fits it before the loop closes."""
    from paraloop_core.fabrication import guide

    bars = (np.array([3.0, 0.0, -80.0]), np.array([3.0, 0.0, 80.0]))
    j = joints.layout(0, np.zeros(3), 12 * Z, Z, bars, (5.0, 5.0), 7.0, "m3", GENERIC,
                      eps=0.05)
    assert (j.kind, j.rod_side, j.cut) == ("dowel", 0, (False, False))
    assert not any(p.printed for p in j.pieces)
    assert all(j.lower[0] <= p.s0 and p.s1 <= j.upper[1] for p in j.pieces)
    assert min(held(j)) >= profiles.ENGAGE_TARGET * j.axle_d - 1e-9
    assert j.upper[1] - j.axle.s1 >= GENERIC.wall_mm + GENERIC.clearance_mm - 1e-9
    for upper in (False, True):  # both holes blind: a floor a wall thick under each face
        box = csg.manifold(parts.holes(j, upper, 30.0)).bounding_box()
        assert (box[5] <= j.upper[1] - GENERIC.wall_mm + 1e-9) if upper else \
            (box[2] >= j.lower[0] + GENERIC.wall_mm - 1e-9)
    assert "before the loop is closed" in guide._joint_text(j, 0)
    # without a rod the loop closes on another joint; with one, on the rod
    from dataclasses import replace

    ring = [replace(pin("m3"), index=i) for i in range(6)]
    ring[5] = replace(j, index=5)
    order = [x.index for x in guide.assembly_order(tuple(ring))]
    assert sorted(order) == list(range(6)) and order[-1] == 4
    ring[2] = replace(pin("rod", rod_side=0), index=2)
    assert [x.index for x in guide.assembly_order(tuple(ring))] == [0, 1, 3, 4, 5, 2]


def test_a_bar_cut_across_its_core_is_said():
    """A bar leaning over the pin into the neighbour's zone past the split is cut across its
    core there: the layout says so (:func:`joints.cut_sides`; the export then prefers another
    realization or rod); crossing bars are not cut."""
    over = (np.array([40.0, 0.0, 60.0]), np.array([0.0, 40.0, 0.0]))
    j = joints.layout(0, np.zeros(3), 12 * Z, Z, over, (1.0, 5.0), 7.0, "m3", GENERIC,
                      eps=0.05)
    assert j.cut == (True, False)
    # link j's centre line just past the split (where link j+1's zone begins) lies within
    # the zone cut's radius of the axis
    s = j.split + j.gap / 2 + 0.1
    assert s * 40.0 / 60.0 < j.reach + GENERIC.clearance_mm + parts.EPS_MM
    for kind, side in KINDS:
        assert pin(kind, 12.0, rod_side=side).cut == (False, False)


def test_the_grounded_joint_holds_the_rod():
    asm = F.printed().assembly
    (j,) = [j for j in asm.joints if j.kind == "rod"]
    rod = asm.base.rod
    assert j.axle_d == rod.d_mm and min(held(j)) >= profiles.ENGAGE_TARGET * rod.d_mm - 1e-9
    axle = next(p for p in j.pieces if p.role == "rod")
    assert axle.s0 <= j.lower[0] and axle.s1 >= j.upper[1]  # through both bosses
    fixed = j.rod_side
    assert j.bore[fixed] == pytest.approx(rod.d_mm / 2)  # press fit in the grounded link
    assert j.bore[1 - fixed] == pytest.approx(rod.d_mm / 2 + GENERIC.clearance_mm
                                              + GENERIC.hole_allowance_mm / 2)
    assert asm.base.link == (j.index + fixed) % 6


@pytest.mark.parametrize("kind", ["m3", "m4"])
@pytest.mark.parametrize("length", [0.0, 3.0, 10.0, 21.0])
def test_stock_screw_passes_the_nut(kind, length):
    f = profiles.FASTENERS[kind]
    j = pin(kind, length, boss=7.0)
    pieces = {p.role: p for p in j.pieces}
    head, screw = pieces["screw head"], pieces["screw"]
    washer, nut = pieces["thrust washer"], pieces["lock nut"]
    assert j.screw_mm in f.lengths_mm and screw.s1 - screw.s0 == pytest.approx(j.screw_mm)
    outer = sorted((p for p in j.pieces if p.role == "washer"), key=lambda p: p.s0)
    assert len(outer) == 2
    # head on a washer on link j's outer face: nothing is sunk into the boss
    assert (outer[0].s0, outer[0].s1) == pytest.approx((j.lower[0] - f.washer_t_mm, j.lower[0]))
    assert head.s1 == pytest.approx(outer[0].s0) and screw.s0 == pytest.approx(head.s1)
    assert head.s1 - head.s0 == pytest.approx(f.head_h_mm)
    # the thrust washer fills the gap between the bosses
    assert (washer.s0, washer.s1) == pytest.approx((j.lower[1], j.upper[0]))
    assert j.gap == f.washer_t_mm
    # washer and lock nut on link j+1's outer face, the tip past the nut by the protrusion
    assert (outer[1].s0, outer[1].s1) == pytest.approx((j.upper[1], j.upper[1] + f.washer_t_mm))
    assert nut.s0 == pytest.approx(outer[1].s1)
    assert nut.s1 - nut.s0 == pytest.approx(f.nut_h_mm) and nut.sides == 6
    assert screw.s1 - nut.s1 >= joints.PROTRUDE_MM - 1e-9
    # the shortest stock length that passes the nut: the next shorter one would not
    need = nut.s1 + joints.PROTRUDE_MM - screw.s0
    assert j.screw_mm >= need - 1e-9
    assert all(v < need - 1e-9 for v in f.lengths_mm if v < j.screw_mm)
    # every boss holds its axle over the engagement target
    assert min(held(j)) >= profiles.ENGAGE_TARGET * f.d_mm - 1e-9


def test_the_hardware_sits_outside_the_bosses():
    """No piece of metal hardware but the screw's shank lies inside a boss's range: no
    counterbore or nut trap is cut, so a boss needs a wall only around its bore."""
    for kind in ("m3", "m4"):
        j = pin(kind, 10.0, boss=7.0)
        for p in j.pieces:
            if p.role in ("screw", "thrust washer"):
                continue
            for lo, hi in (j.lower, j.upper):
                assert p.s1 <= lo + 1e-9 or p.s0 >= hi - 1e-9, (kind, p.role)


def test_printed_pin_and_its_cap():
    c = GENERIC.clearance_mm
    j = pin("printed-pin", 10.0)
    pieces = {p.role: p for p in j.pieces}
    head, shaft, cap = pieces["pin head"], pieces["pin"], pieces["pin cap"]
    assert all(p.printed for p in j.pieces)
    # the head and the cap stand the clearance off the bosses' outer faces
    assert head.s1 == pytest.approx(j.lower[0] - c) and shaft.s0 == pytest.approx(head.s1)
    assert cap.s0 == pytest.approx(j.upper[1] + c)
    assert shaft.s1 - cap.s0 == pytest.approx(profiles.PRINTED_CAP_DEPTH_MM)
    assert shaft.radius == profiles.PRINTED_PIN_D_MM / 2
    assert j.bore == pytest.approx((shaft.radius + c + GENERIC.hole_allowance_mm / 2,) * 2)
    assert head.radius < j.boss_radius and cap.radius < j.boss_radius


def test_refusals():
    with pytest.raises(FabricationError, match="boss radius") as err:
        pin("m3", boss=2.0)
    assert err.value.reason == "bad-parameters"
    for kind in ("print-in-place", "m5"):
        with pytest.raises(FabricationError, match="cannot be laid out"):
            pin(kind)


@pytest.mark.parametrize(("kind", "stock"), [("m2", 30.0), ("m3", 50.0), ("m4", 60.0)])
def test_a_joint_longer_than_stock_screws_turns_on_a_rod_cut_to_length(kind, stock):
    """Just inside the longest stock screw: a screw joint; past it: a dowel (a steel rod of
    the screw's diameter cut to length), glued in link j's boss, capped past link j+1's,
    each boss holding it at least the engagement target."""
    f = profiles.FASTENERS[kind]
    fits = [L for L in np.arange(10.0, 80.0, 0.5) if pin(kind, L, boss=7.0).kind == kind]
    assert fits and max(fits) < 80.0
    j = pin(kind, max(fits), boss=7.0)
    assert j.screw_mm == stock and not j.beyond_stock
    j = pin(kind, max(fits) + 0.5, boss=7.0)
    assert j.kind == "dowel" and j.beyond_stock and j.screw_mm is None
    assert j.fixed_link == 0 and j.axle_d == f.d_mm
    cap = next(p for p in j.pieces if p.role == "dowel cap")
    assert cap.printed and cap.s0 > j.upper[1]  # past link j+1's outer face
    assert j.axle.s1 - j.axle.s0 > stock - 10.0
    assert min(held(j)) >= profiles.ENGAGE_TARGET * f.d_mm - 1e-9
    assert "cut a" in guide._joint_text(j, 0) and "steel rod" in guide._joint_text(j, 0)


@pytest.mark.parametrize(("kind", "side"), KINDS)
def test_envelope_bounds_every_piece(kind, side):
    """Bosses and printed pieces lie within ``B + x_boss`` of the pin, metal pieces within
    ``x_hard`` (the capsules the sizing keeps apart): checked on the rims of every solid."""
    j = pin(kind, 10.0, boss=7.0, rod_side=side)
    x_boss, x_hard = joints.envelope(j)
    phi = np.linspace(0.0, 2 * np.pi, 24, endpoint=False)
    ring = np.stack([np.cos(phi), np.sin(phi), 0 * phi], 1)

    def rims(s0: float, s1: float, r: float) -> np.ndarray:
        return np.concatenate([r * ring + s * Z for s in (s0, s1)])

    def far(x: np.ndarray) -> float:
        return float(F.point_segment(x, np.zeros(3), j.length * Z).max())

    for s0, s1 in (j.lower, j.upper):
        assert far(rims(s0, s1, j.boss_radius)) <= j.boss_radius + x_boss + 1e-9
    for p in j.pieces:
        bound = j.boss_radius + x_boss if p.printed else x_hard
        assert far(rims(p.s0, p.s1, p.radius)) <= bound + 1e-9, p.role
    assert j.reach == max(j.boss_radius, *(p.radius for p in j.pieces))


# --- the split between the two bars of a joint ---------------------------------------------


def _surface(start: np.ndarray, d: np.ndarray, length: float, r: float) -> np.ndarray:
    """Points ``(n, 3)`` on the round bar of radius r from ``start`` along unit ``d`` (the hex
    bar of corner radius r lies inside it)."""
    e1 = np.cross(d, [1.0, 0, 0] if abs(d[0]) < 0.9 else [0, 1.0, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    lam = np.linspace(0.0, length, 601)[:, None, None]
    phi = np.linspace(0.0, 2 * np.pi, 48, endpoint=False)[None, :, None]
    rr = np.array([0.0, r])[None, None, :, None]
    disc = (np.cos(phi) * e1 + np.sin(phi) * e2)[..., None, :] * rr
    return (start + lam[..., None] * d + disc).reshape(-1, 3)


def _sides_kept(length, lower, upper, radii, boss, gap, eps) -> tuple[float, float, tuple]:
    """``(lowest z of link j+1's bar, highest z of link j's)`` within the zone cut's radius of
    the axis (z), and the split."""
    m, notch = joints.split_point(length, lower, upper, Z, radii, boss, gap, eps)
    cut = boss + gap + eps
    out = []
    for start, bar, r in ((np.zeros(3), lower, radii[0]), (length * Z, upper, radii[1])):
        n = float(np.linalg.norm(bar))
        x = _surface(start, bar / n, n, r)
        near = np.hypot(x[:, 0], x[:, 1]) < cut
        out.append(x[near, 2])
    lo = float(out[0].max()) if len(out[0]) else -np.inf
    up = float(out[1].min()) if len(out[1]) else np.inf
    return lo, up, (m, notch)


def test_split_moves_away_from_a_bar_that_leans_back():
    # pin from (0,0,0) to (0,0,10); link j+1's bar leans back over the pin, link j's away
    lower, upper = np.array([0.0, -30.0, -20.0]), np.array([7.0, 0.0, -10.0])
    lo, up, (m, notch) = _sides_kept(10.0, lower, upper, (1.0, 1.0), 3.3, 0.3, 0.05)
    assert notch == (0.0, 0.0) and m < 5.0 - 1.0  # towards E_j, off the middle
    assert up >= m + 0.15 + 0.05 - 1e-9 and lo <= m - 0.15 - 0.05 + 1e-9
    # both bars lean over the pin: no split clears both, the middle of the conflict
    m2, notch2 = joints.split_point(10.0, np.array([0.0, -30.0, 16.0]), upper, Z, (1.0, 1.0),
                                    3.3, 0.3, 0.05)
    assert notch2[0] > 0 and notch2[1] > 0 and notch2[0] == pytest.approx(notch2[1])


unit = st.tuples(*[st.floats(-1.0, 1.0)] * 3).filter(lambda v: 0.2 < np.linalg.norm(v))


@settings(max_examples=40, deadline=None)
@given(unit, unit, st.floats(0.0, 25.0), st.floats(5.0, 60.0), st.floats(5.0, 60.0),
       st.floats(1.0, 5.0), st.floats(0.0, 3.0))
def test_split_keeps_each_bar_on_its_side(dl, du, length, nl, nu, r, extra):
    """Wherever the split clears both bars (no notch), each bar's material within the zone
    cut's radius of the axis lies on its own side of the split, past the half gap and eps."""
    lower = np.array(dl) / np.linalg.norm(dl) * nl
    upper = np.array(du) / np.linalg.norm(du) * nu
    gap, eps = 0.5, 0.05
    lo, up, (m, notch) = _sides_kept(length, lower, upper, (r, r), r + extra, gap, eps)
    if notch == (0.0, 0.0):
        assert lo <= m - gap / 2 - eps + 1e-6
        assert up >= m + gap / 2 + eps - 1e-6


# --- print in place ------------------------------------------------------------------------


def _turned(angle_deg: float) -> np.ndarray:
    a = np.radians(angle_deg)
    return np.array([np.sin(a), 0.0, np.cos(a)])


def test_print_in_place_allowed_when_the_axes_nearly_agree():
    assert joints.in_place_refusal(np.tile(Z, (6, 1))) is None
    assert joints.in_place_refusal(np.tile([0.3, -0.5, 0.8], (6, 1))) is None
    # five vertical, one 45 deg off: the halfway direction leans 22.5 deg from each
    assert joints.in_place_refusal(np.array([Z] * 5 + [_turned(45.0)])) is None
    # an axis and its reverse are the same joint axis
    assert joints.in_place_refusal(np.array([Z, -Z, Z, -Z, Z, _turned(-40.0)])) is None


def _lean(message: str) -> tuple[float, list[float]]:
    top = float(re.search(r"lean up to (\d+) deg", message).group(1))
    each = [float(a) for a in re.findall(r"\d: (\d+) deg", message)]
    return top, each


def test_print_in_place_refused_with_the_angles():
    axes = np.array([Z] * 5 + [_turned(70.0)])
    why = joints.in_place_refusal(axes)
    assert why is not None and "30 deg" in why and "--joints m3" in why
    top, each = _lean(why)
    assert 35.0 <= top <= 37.0 and len(each) == 6 and max(each) == pytest.approx(top, abs=1)


def test_a_spatial_loop_is_refused_naming_its_angles():
    axes = loops.factor_axes(F.loop_factors())[:, :3]
    why = joints.in_place_refusal(axes)
    assert why is not None
    top, each = _lean(why)
    assert len(each) == 6 and max(each) == pytest.approx(top, abs=1)
    # the best print direction, searched independently (a fine grid, then refined)
    d = axes / np.linalg.norm(axes, axis=1, keepdims=True)
    th, ph = np.meshgrid(np.linspace(0, np.pi / 2, 181), np.linspace(0, 2 * np.pi, 721))
    ups = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1)
    lean = np.degrees(np.arccos(np.clip(np.abs(ups @ d.T), 0, 1))).max(-1)
    best = float(lean.min())
    assert best > joints.IN_PLACE_TILT_DEG
    assert best - 0.6 <= top <= best + 3.0  # the production grid is coarser (4000 directions)
