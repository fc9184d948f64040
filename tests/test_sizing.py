"""Size and radii from the certified pair bounds (:mod:`fabrication.sizing`), the bed fit
(:mod:`fabrication.bed`) and the choice among candidate realizations (:mod:`printable`)."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import fab_fixtures as F
import numpy as np
import pytest
from independent.segdist import segment_distance

from paraloop_core.errors import FabricationError, RealizationError
from paraloop_core.fabrication import (
    bed,
    choice,
    flat,
    joints,
    printable,
    profiles,
    remedy,
    rows,
    sizing,
    stiffness,
)
from paraloop_core.linkage import singularity

GENERIC = profiles.PRINTERS["generic"]
ROD = profiles.DEFAULT_ROD
SQ3 = np.sqrt(3.0)


def capsules(e: int, radius: np.ndarray, boss: np.ndarray, env: np.ndarray
             ) -> list[tuple[float, float]]:
    """``(radius, reach past the segment's ends)`` of the capsules about edge ``e`` (module
    docstring of sizing: a bar's hexagon, a pin's bosses and its metal pieces)."""
    if e % 2 == 0:
        return [(float(radius[e // 2]), 0.0)]
    j = e // 2
    return [(float(boss[j]), float(env[j, 0]))] + ([(0.0, float(env[j, 1]))]
                                                    if env[j, 1] > 0 else [])


def worst_room(b: rows.Bounds, k: float, radius: np.ndarray, boss: np.ndarray,
               env: np.ndarray, gaps: np.ndarray, samples: int = 720) -> float:
    """Least ``distance - radii - reaches - gap`` (mm) of every pair of capsules that must keep
    a gap, the distance of their centre segments measured over the cycle at ``samples``
    parameters (an independent segment distance, the link poses straight from the loop), not
    the certified bounds: >= 0 when the capsules keep their gaps at those samples."""
    jf = F.real().joint_factors
    pts = b.points * k
    edge = np.stack([pts, np.roll(pts, -1, axis=0)], 1)  # edge e: points e, e + 1
    u = (np.arange(samples) + 0.5) / samples
    worst = np.inf

    def check(e1: int, e2: int, la: int, lb: int, gap: float) -> None:
        nonlocal worst
        rel = F.relative_poses(jf, k, la, u)[:, lb]
        moved = np.einsum("tij,nj->tni", rel[:, :3, :3], edge[e2]) + rel[:, None, :3, 3]
        dist = segment_distance(edge[e1][0], edge[e1][1], moved[:, 0], moved[:, 1]).min()
        for r1, x1 in capsules(e1, radius, boss, env):
            for r2, x2 in capsules(e2, radius, boss, env):
                worst = min(worst, float(dist - r1 - x1 - r2 - x2 - gap))

    for (e1, e2, la, lb) in b.rows:
        check(int(e1), int(e2), int(la), int(lb), float(gaps[la, lb]))
    for i in range(6):
        j = (i + 1) % 6
        check(2 * i, 2 * j, i, j, float(gaps[i, j]))  # consecutive bars
        # consecutive pins are both fixed in link i + 1: their bosses of links i and i + 2
        check(2 * i + 1, 2 * j + 1, j, j, float(gaps[i, (i + 2) % 6]))
    return worst


@pytest.fixture(scope="module")
def bounds() -> rows.Bounds:
    return rows.bounds_of(F.real())


def _inputs(b: rows.Bounds, size: float = F.SIZES["m4"], cap: float = 12.0):
    """A programme whose rows bind: M4 joints at ``size``, bars up to ``cap`` mm."""
    k = size / b.extent
    rmin = sizing.min_radii(b, k, GENERIC, "m4", 1)
    bmin = sizing.min_boss(GENERIC, "m4", ROD)
    env = rows.envelopes(F.plan("m4").layouts)
    gaps = stiffness.required_gaps(np.full(6, 0.2))
    return k, rmin, cap, bmin, env, gaps


def test_every_row_holds_for_the_returned_radii(bounds):
    k, rmin, cap, bmin, env, gaps = _inputs(bounds)
    r, boss = rows.radii(bounds, k, rmin, cap, bmin, env, gaps)
    assert np.all(r >= rmin - 1e-9) and np.all(r <= cap + 1e-9) and np.all(boss >= bmin - 1e-9)
    # each boss holds a fillet around both bars it joins
    assert np.all(boss >= rows.BOSS_PER_BAR * np.maximum(r, np.roll(r, -1)) - 1e-9)
    # the certified rows, written out here: r_a + r_b + gap <= k L - x_a - x_b
    for (e1, e2, la, lb), low in zip(bounds.rows, bounds.lower, strict=True):
        for r1, x1 in capsules(int(e1), r, boss, env):
            for r2, x2 in capsules(int(e2), r, boss, env):
                assert r1 + r2 + gaps[la, lb] <= k * low - x1 - x2 + 1e-9
    # the capsules keep their gaps over the cycle, measured without the certificate
    assert worst_room(bounds, k, r, boss, env, gaps) >= -1e-6
    # the thinnest bar is the largest the rows allow: a hair thicker is infeasible
    t = float(r.min())
    assert t < cap  # the rows bind here, not the cap
    assert rows.radii(bounds, k, np.maximum(rmin, t * 1.001), cap, bmin, env, gaps) is None
    assert len(np.unique(np.round(r, 6))) > 1  # and the others grow past it where they can


def test_infeasible_programmes_return_none(bounds):
    k, rmin, cap, bmin, env, gaps = _inputs(bounds)
    assert rows.radii(bounds, k, rmin, cap, bmin, env, gaps + 100.0) is None
    assert rows.radii(bounds, 0.1 * k, rmin, cap, bmin, env, gaps) is None
    # a metal piece alone reaching past a row's room: nothing to shrink
    big = env.copy()
    big[:, 1] = 1e3
    assert rows.radii(bounds, k, rmin, cap, bmin, big, gaps) is None
    # a floor above the cap
    assert rows.radii(bounds, k, np.full(6, cap + 1.0), cap, bmin, env, gaps) is None


def test_plans_keep_their_required_gaps(bounds):
    for kind in ("m3", "m4", "printed-pin"):
        p = F.plan(kind)
        assert p.size_mm == pytest.approx(F.SIZES[kind]) and p.scale * bounds.extent == \
            pytest.approx(p.size_mm)
        gaps = stiffness.required_gaps(p.deflection.total)
        assert np.allclose(p.gaps, gaps)
        room = worst_room(bounds, p.scale, p.radii, p.boss, rows.envelopes(p.layouts), p.gaps)
        assert room >= -1e-6, kind


def test_min_radii_and_caps(bounds):
    k = 300.0 / bounds.extent
    length = bounds.bar_lengths * k
    flat = (F.GENERIC.wall_mm + 1.7) / (SQ3 / 2)  # M3 bore 1.7 mm under the bar's flat
    aims = sizing.min_radii(bounds, k, GENERIC, "m3", 0)
    assert aims == pytest.approx(np.maximum.reduce([np.full(6, 7.0 / SQ3), length / (25 * SQ3),
                                                    np.full(6, flat)]))
    floors = sizing.min_radii(bounds, k, GENERIC, "m3", 1)
    assert floors == pytest.approx(np.maximum.reduce([np.full(6, 6.4 / SQ3),
                                                      length / (28 * SQ3), np.full(6, flat)]))
    assert sizing.min_radii(bounds, k, GENERIC, "m3", 3) == pytest.approx(np.full(6, flat))
    assert [sizing.bar_cap(s) for s in (100.0, 200.0, 250.0, 400.0)] == pytest.approx(
        [4.5, 5.6, 7.0, 8.0])
    # the rod's running bore (3 + 0.3 + 0.1) with the wall and its room
    assert sizing.min_boss(GENERIC, "m3", ROD) == pytest.approx(
        3.0 + 0.3 + 0.1 + 1.6 + joints.BOSS_ROOM_MM)


def _lw(p: sizing.Plan, b: rows.Bounds) -> np.ndarray:
    return b.bar_lengths * p.scale / (p.radii * SQ3)


def test_aims_then_floors(bounds):
    """At the fixtures' size (220 mm) the aims hold (bars >= 7 mm wide, <= 25 times as long,
    gaps 10 % over 3x the deflections); at 400 mm only the floors (6 mm, 30) and the plan
    says so."""
    p = F.plan("m3")
    assert p.level == 0 and p.aims_met
    assert np.all(p.radii * SQ3 >= sizing.WIDTH_AIM_MM - 1e-9)
    assert np.all(_lw(p, bounds) <= sizing.LW_AIM + 1e-9)
    big = sizing.plan(F.real(), GENERIC, F.PLA, "m3", ROD, size_mm=400.0)
    assert big.level == 1 and not big.aims_met
    k = 400.0 / bounds.extent
    matrix = stiffness.torque_matrix(F.real())
    assert sizing.at_scale(F.real(), bounds, k, GENERIC, F.PLA, "m3", ROD, 0.05, matrix,
                           0) is None
    assert np.all(big.radii * SQ3 >= sizing.WIDTH_MM - 1e-9)
    assert np.all(_lw(big, bounds) <= sizing.LW_MAX + 1e-9)
    assert sizing.to_dict(big, GENERIC, bounds)["level"] == "floors"


def test_the_floors_precheck_only_skips_what_has_no_plan(bounds, monkeypatch):
    """:func:`sizing._floors_fit` skips a level's deflection bounds at a size where bars at
    their floors with the least gaps already break a row: over sizes from roomy to cramped,
    every plan found with the precheck is the one found without it, and the precheck
    skips some sizes (it would be pointless otherwise)."""
    real, matrix = F.real(), stiffness.torque_matrix(F.real())

    def plans() -> list:
        return [sizing.at_scale(real, bounds, s / bounds.extent, GENERIC, F.PLA, "m3", ROD,
                                0.05, matrix, level) for s in (130.0, 160.0, 220.0, 300.0, 400.0)
                for level in (0, 1)]

    skipped = [not sizing._floors_fit(bounds, s / bounds.extent, sizing.min_radii(
        bounds, s / bounds.extent, GENERIC, "m3", level), GENERIC, "m3", 0.05,
        sizing.min_boss(GENERIC, "m3", ROD)) for s in (130.0, 160.0, 220.0, 300.0, 400.0)
        for level in (0, 1)]
    with_check = plans()
    monkeypatch.setattr(sizing, "_floors_fit", lambda *a: True)
    without = plans()
    assert any(skipped) and not all(skipped)
    for a, b, skip in zip(with_check, without, skipped, strict=True):
        assert (a is None) == (b is None) and (not skip or b is None)
        if a is not None:
            assert a.radii == pytest.approx(b.radii) and a.level == b.level


def test_too_small_a_size_is_refused():
    with pytest.raises(FabricationError, match="at 120 mm") as err:
        sizing.plan(F.real(), GENERIC, F.PLA, "m3", ROD, size_mm=120.0)
    assert err.value.reason == "bad-parameters"


def test_report_entry_and_the_limiting_pair(bounds):
    p = F.plan("m4")
    d = sizing.to_dict(p, GENERIC, bounds)
    assert d["bar_width_mm"] == pytest.approx(p.radii * SQ3)
    assert d["level"] == "aims" and d["size_mm"] == pytest.approx(p.size_mm)
    lim = d["limiting_pair"]
    width = p.radii * SQ3
    short = np.maximum(6.4 / width, p.deflection.lengths / width / 28.0)
    thin = int(np.argmax(short))
    assert lim["thinnest_bar_link"] == thin and thin in lim["links"]
    assert lim["bar_width_mm"] == pytest.approx(width[thin])
    assert lim["room_left_mm"] >= -1e-6  # the plan keeps every row
    # the consecutive bars on the thin bar's joints count too (two links on one joint)
    k, r = p.scale, p.radii
    joint_rows = [k * bounds.joint_lower[i] - r[i] - r[(i + 1) % 6] - p.gaps[i, (i + 1) % 6]
                  for i in (thin, (thin - 1) % 6) if np.isfinite(bounds.joint_lower[i])]
    assert lim["room_left_mm"] <= min(joint_rows, default=np.inf) + 1e-9


def test_the_limiting_pair_of_equal_bars_is_the_longest_bars(bounds):
    """Bars all as thick (the last level's): the pair named is the longest bar's, the one
    furthest from the length per width a printed bar should keep, with what it reaches."""
    p = F.plan("m4")
    p = replace(p, radii=np.full(6, p.radii.min()))
    lim = sizing.to_dict(p, GENERIC, bounds)["limiting_pair"]
    longest = int(np.argmax(p.deflection.lengths))
    assert lim["thinnest_bar_link"] == longest and longest in lim["links"]
    assert lim["length_per_width"] == pytest.approx(
        p.deflection.lengths[longest] / (p.radii[0] * SQ3))


def test_automatic_size_fits_the_bed():
    """Without a size, the largest at which the predicted parts fit the bed: the parts may
    not grow, and a slightly larger bed gives a larger size."""
    r = F.real()

    def fit(p):
        return bed.predicted_fit(p, r.points, GENERIC)

    p = sizing.plan(r, GENERIC, F.PLA, "m3", ROD, fit=fit)
    assert fit(p) >= 1.0 and p.level == 0
    assert sizing.MIN_SIZE_MM <= p.size_mm <= bed.bed_scale(r.points, GENERIC) * \
        rows.bounds_of(r).extent + 1e-6


# --- the bed -------------------------------------------------------------------------------


def test_bed_fit_in_any_orientation():
    ext = np.array([[200.0, 240.0, 10.0], [260.0, 1.0, 1.0], [330.0, 1.0, 1.0],
                    [260.0, 220.0, 220.0], [300.0, 14.0, 11.0]])
    # a long thin bar lies diagonally on the 250 x 210 bed (diagonal 326 mm)
    assert bed.fits_bed(ext, GENERIC).tolist() == [True, True, False, False, True]
    f = bed.fit_factor(ext[1:2], GENERIC)[0]
    assert bed.fits_bed(ext[1:2] * f * 0.999, GENERIC)[0]
    assert not bed.fits_bed(ext[1:2] * f * 1.01, GENERIC)[0]


def test_footprint_turn_known_answers():
    bed_xy = np.array([250.0, 210.0])
    f, turn = bed.footprint_turn(np.array([100.0, 50.0]), bed_xy)
    assert turn == 0.0 and f == pytest.approx(min(250 / 100, 210 / 50))
    # a 300 x 12 footprint fits only turned: the best factor by brute force over angles
    w, h = 300.0, 12.0
    a = np.radians(np.linspace(0.0, 90.0, 90001))
    brute = np.minimum(250 / (w * np.cos(a) + h * np.sin(a)), 210 / (w * np.sin(a) + h *
                                                                      np.cos(a))).max()
    f, turn = bed.footprint_turn(np.array([w, h]), bed_xy)
    assert 1.0 < f <= brute + 1e-12 and f == pytest.approx(brute, rel=2e-3)
    c, s = np.cos(turn), np.sin(turn)  # the turned box fits at that factor
    assert f * (w * c + h * s) <= 250 + 1e-9 and f * (w * s + h * c) <= 210 + 1e-9


def test_bed_scale_fills_the_bed_with_the_largest_skeleton():
    pts = F.real().points
    k = bed.bed_scale(pts, GENERIC)
    s, e = pts[0::2], pts[1::2]
    worst = np.inf
    for i in range(6):  # each link's bar and half of each of its pins, in its own axes
        c = np.array([(e[i - 1] + s[i]) / 2, s[i], e[i], (e[i] + s[(i + 1) % 6]) / 2]) * k
        c = c - c.mean(0)
        ext = np.ptp(c @ np.linalg.svd(c)[2].T, axis=0)
        worst = min(worst, float(bed.fit_factor(ext[None], GENERIC)[0]))
    assert worst == pytest.approx(1.0)


# --- the choice among candidates -----------------------------------------------------------


def test_choice_names_every_failure_and_keeps_the_sized():
    def refused():
        raise RealizationError("no realization in the budget", "not-found")

    good = choice.Candidate("roomy", 4, lambda: (F.real(), None))
    bad = choice.Candidate("thin", 4, refused)
    opts = printable.Options(size_mm=F.SIZE_MM)
    ranked, tried, _ = choice.choose([bad, good], opts)
    assert [c.label for c, *_ in ranked] == ["roomy"] and tried[0].startswith("thin: no reali")
    assert ranked[0][3].size_mm == pytest.approx(F.SIZE_MM)
    with pytest.raises(FabricationError, match="thin: no realization in the budget"):
        choice.choose([bad], opts)
    small = printable.Options(size_mm=60.0)
    with pytest.raises(FabricationError, match="roomy: at 60 mm") as err:
        choice.choose([good], small)
    # every joint kind of auto was tried: the refusal names them all, not the first
    assert "hardware (m3 or m2)" in str(err.value) and profiles.AUTO_JOINTS == ("m3", "m2")


def test_a_loop_far_from_singular_is_printed_before_a_near_singular_one():
    """Equal plans: the near-singular loop's candidate ranks last, and does not count
    towards the candidates that are enough to choose from."""
    real = F.real()
    near = choice.Candidate("near", 4, lambda: (real, None), near_singular=True)
    cands = [near] + [choice.Candidate(f"ok{k}", 4, lambda: (real, None)) for k in range(3)]
    ranked, tried, _ = choice.choose(cands, printable.Options())
    assert ranked[0][3].aims_met and [c.label for c, *_ in ranked] == ["ok0", "ok1", "near"]
    ranked, _, _ = choice.choose(cands[::-1], printable.Options())
    assert [c.label for c, *_ in ranked] == ["ok2", "ok1"]  # enough before the near one
    assert singularity.loop_status(np.array([1.0, 2e-3, 1e-3, 1e-9, 0.0])) == \
        ["ok", "ok", "near-singular", "singular", "singular"]


@pytest.mark.parametrize("lifted", [False, True])
def test_more_candidates_are_sized_while_each_would_print_over_supports(lifted, monkeypatch):
    """Sizing stops after :data:`choice.ENOUGH_SIZED` candidates, or
    :data:`choice.FLAT_SEARCH` more while each one's own layouts leave a link no flat."""
    real = F.real()
    monkeypatch.setattr(choice, "_lifted_by_plan", lambda *a: lifted)
    cands = [choice.Candidate(f"c{k}", 4, lambda: (real, None)) for k in range(10)]
    # a size that meets no aims: the count alone stops the sizing
    ranked, tried, _ = choice.choose(cands, printable.Options(size_mm=0.6 * F.SIZE_MM))
    assert not any(plan.aims_met for *_, plan in ranked)
    extra = choice.FLAT_SEARCH if lifted else 0
    assert len(ranked) == len(tried) == choice.ENOUGH_SIZED + extra


def test_the_sizing_predicts_the_links_a_build_lifts():
    """:func:`choice._lifted_by_plan` agrees with the built parts' print flats (before the
    grounding rod re-lays a joint)."""
    real, opts = F.real(), printable.Options(size_mm=F.SIZE_MM)
    plan = choice._plan(real, opts)
    asm, plan, _ = printable._fit_and_build(real, None, plan, opts)
    off_flat = [i for i in range(6) if not flat.lies_flat(asm.slack[i])]
    assert choice._lifted_by_plan(real, plan, opts) == bool(off_flat)
    assert printable._keeled(asm) == off_flat and not printable._lifted(asm)


def test_a_keel_that_fails_the_verification_is_narrowed_then_taken_off(monkeypatch):
    """Every link lifted (a flat 1 mm under its bar's face): each gets a wide keel; a pair
    the verification fails loses a level of its deeper keel (of equals the first link's:
    narrow, then none; rebuilt, grounded and verified again; the others keep theirs), the
    report says so, and the STEP helper gets the final parts last."""
    monkeypatch.setattr(flat, "lift", lambda slack: 1.0)
    monkeypatch.setattr(flat, "lies_flat", lambda slack: False)
    real_verify, calls = printable.check.verify, []

    def verify(asm, *args, **kwargs):
        ver = real_verify(asm, *args, **kwargs)
        calls.append(asm)
        if len(calls) <= 2:  # the first two verifications fail links 0 and 3
            ver["pairs"][2]["colliding_samples"] = 5
        return ver

    monkeypatch.setattr(printable.check, "verify", verify)
    handed = []
    cand = choice.Candidate("test loop", 4, lambda: (F.real(), None))
    out = printable.make([cand], printable.Options(size_mm=F.SIZE_MM, samples=F.SAMPLES),
                         on_parts=handed.append)
    assert out.report["verification"]["pairs"][2]["links"] == [0, 3]
    assert [a.keel_levels for a in calls] == [(2,) * 6, (1,) + (2,) * 5, (0,) + (2,) * 5]
    narrow, wide = (F.mesh_of(calls[k].links[0].manifold) for k in (1, 0))
    assert narrow.volume < wide.volume  # the narrow keel is less of the wide one
    assert out.report["keels_mm"] == [0.0, 1.0, 1.0, 1.0, 1.0, 1.0]
    # the STEP helper got the parts before their verification, then the final ones
    assert handed[0] is calls[0] and handed[-1] is out.assembly is calls[-1]
    tried = out.report["choice"]["tried"]
    assert any("the keel of link 0 comes too close to another link: link 0 narrowed" in t
               for t in tried)
    assert any("link 0 without" in t for t in tried)
    assert any("link 0 cannot lie on the bar's face" in w for w in out.report["warnings"])


def test_a_candidate_that_falls_apart_without_its_keel_gives_way(monkeypatch):
    """Random 62206 with printed pins: a keel that failed the verification came off and a
    link then fell apart, which refused the whole export. Now that candidate is not built
    (the report says why) and the next one is: here the first candidate's keels fail, its
    rebuild falls apart, the second (the same loop) verifies and is printed."""
    monkeypatch.setattr(flat, "lift", lambda slack: 1.0)
    monkeypatch.setattr(flat, "lies_flat", lambda slack: False)
    real_verify, real_build, calls = printable.check.verify, printable._fit_and_build, []

    def verify(asm, *args, **kwargs):
        ver = real_verify(asm, *args, **kwargs)
        calls.append(asm)
        if len(calls) == 1:  # the first candidate's keels come too close to another link
            ver["pairs"][2]["colliding_samples"] = 5
        return ver

    def build(real, ee, plan, opts, keel_levels=(2,) * 6):
        if keel_levels != (2,) * 6:  # rebuilt without a keel: a bar is cut through
            raise FabricationError("link 0 falls apart into 2 pieces", "falls-apart")
        return real_build(real, ee, plan, opts, keel_levels)

    monkeypatch.setattr(printable.check, "verify", verify)
    monkeypatch.setattr(printable, "_fit_and_build", build)
    cands = [choice.Candidate(f"c{k}", 4, lambda: (F.real(), None)) for k in range(2)]
    out = printable.make(cands, printable.Options(size_mm=F.SIZE_MM, samples=F.SAMPLES))
    assert out.candidate == "c1" and len(calls) == 2
    assert any(t.startswith("c0: not built without its keel (link 0 falls apart")
               for t in out.report["choice"]["tried"])


def test_print_in_place_is_refused_at_once():
    cand = choice.Candidate("roomy", 4, lambda: (F.real(), None))
    with pytest.raises(FabricationError, match="lean up to") as err:
        choice.choose([cand], printable.Options(joints="print-in-place"))
    assert err.value.reason == "bad-parameters"
    assert str(err.value).count("deg") >= 8  # the limit, the worst lean, each joint's


# --- what a refusal for room says would work (remedy) ------------------------------------------


def _room_from(factor: float):
    """A sizer that finds room only on a bed (or at a size) ``factor`` times the generic's."""
    generic = printable.Options()

    def size(real, opts, ee):
        grown = (opts.size_mm / 200.0 if opts.size_mm is not None else
                 opts.printer.bed_mm[0] / generic.printer.bed_mm[0])
        if grown < factor:
            raise sizing.NoRoomError("no room", "bad-parameters")
        return SimpleNamespace(size_mm=0.9 * grown * 250.0)

    return size


def test_refusal_names_the_smallest_bed_that_has_room():
    hint = remedy.larger_print([("loop 1", None, None), ("loop 2", None, None)],
                               printable.Options(), _room_from(1.4))
    # 1.25 x the bed has no room, 1.5 x has: 250 x 210 x 210 -> 375 x 315 x 315
    assert "a bed of at least 375 x 315 x 315 mm (--bed 375,315,315)" in hint
    assert "where loop 1 has room for its joints at 338 mm" in hint
    at_size = remedy.larger_print([("loop 1", None, None)], printable.Options(size_mm=200.0),
                                  _room_from(1.9))
    assert "--size-mm 400" in at_size
    assert remedy.larger_print([], printable.Options(), _room_from(1.0)) == ""


def test_refusal_says_when_a_larger_print_would_not_help():
    hint = remedy.larger_print([("loop 1", None, None)], printable.Options(), _room_from(3.5))
    assert "A larger print would not help" in hint and "3 times as large" in hint
    assert "--bed" not in hint


def test_refusal_of_chosen_joints_names_the_default_joints_where_they_fit():
    """A maker who chose printed pins (or M4) and is refused for room is told when the
    default joints (M3 screws) have room on the same bed, before any larger bed."""
    def size(real, opts, ee):
        if opts.joints != "auto":
            raise sizing.NoRoomError("no room", "bad-parameters")
        return SimpleNamespace(kind="m3", size_mm=231.0)

    refused = [("loop 2", None, None)]
    hint = remedy.other_joints(refused, printable.Options(joints="printed-pin"), size)
    assert "--joints auto: M3 screws and lock nuts instead of printed pins and caps" in hint
    assert "loop 2 has room for them at 231 mm" in hint
    message = remedy.refusal(["loop 2: no room"], refused,
                             printable.Options(joints="printed-pin"), size)
    assert message.index("--joints auto") < message.index("Tried:")
    # the default joints already tried, or without room either: nothing said
    assert remedy.other_joints(refused, printable.Options(), size) == ""
    assert remedy.other_joints(refused, printable.Options(joints="m4"),
                               _room_from(1.4)) == ""


def test_thin_bars_name_the_smallest_bed_with_bars_within_the_floors():
    """:func:`remedy.stronger_print`: the smallest larger bed on which a realization's plan
    reaches the floors (a level below thin bars), with its bars; else that none does."""
    def within_from(factor: float):
        def size(real, opts, ee):
            grown = opts.printer.bed_mm[0] / printable.Options().printer.bed_mm[0]
            level = 1 if grown >= factor and real == "good" else 3
            return SimpleNamespace(level=level, size_mm=250.0 * grown,
                                   radii=np.full(6, 4.0), deflection=SimpleNamespace(
                                       lengths=np.full(6, 150.0)))
        return size

    sized = [("loop 1", "thin", None), ("loop 2", "good", None)]
    got = remedy.stronger_print(sized, printable.Options(), within_from(1.2))
    assert got["bed_mm"] == [313.0, 263.0, 263.0] and got["realization"] == "loop 2"
    assert got["bar_width_mm"] == pytest.approx(4.0 * sizing.FLATS)
    assert "--bed 313,263,263), where loop 2 has bars 6.9 mm wide" in got["sentence"]
    assert remedy.stronger_print(sized, printable.Options(), within_from(1.4))["bed_mm"] == \
        [375.0, 315.0, 315.0]
    none = remedy.stronger_print(sized, printable.Options(), within_from(2.0))
    assert none["bed_mm"] is None and "a design whose links pass farther apart" in \
        none["sentence"]
    assert remedy.stronger_print(sized, printable.Options(size_mm=200.0),
                                 within_from(1.2)) == {}


def test_a_smaller_size_is_tried_where_the_bed_size_has_no_room(monkeypatch):
    """Built parts that must shrink to fit the bed: where the size they fit at has no room
    for the joints (the hardware's stock lengths make the room uneven in the size), a little
    smaller sizes are tried (:data:`printable.SMALLER`); where none has room, the candidate
    gives way to the next (here the same realization, whose parts fit)."""
    real, opts = F.real(), printable.Options()
    plan = choice._plan(real, replace(opts, size_mm=F.SIZE_MM))
    sizes = []

    def plan_at(*a, size_mm=None, **k):
        sizes.append(size_mm)
        if size_mm > 0.95 * F.SIZE_MM:
            raise sizing.NoRoomError(f"at {size_mm:.0f} mm no room", "bad-parameters")
        return replace(plan, size_mm=size_mm)

    monkeypatch.setattr(sizing, "plan", plan_at)
    got = printable._smaller(real, None, plan, opts, F.SIZE_MM)
    assert got.size_mm == pytest.approx(0.94 * F.SIZE_MM)
    assert sizes == pytest.approx([F.SIZE_MM, 0.97 * F.SIZE_MM, 0.94 * F.SIZE_MM])
    with pytest.raises(sizing.NoRoomError):
        printable._smaller(real, None, plan, opts, 2 * F.SIZE_MM)
    # in the choice of what to build: the candidate without room is passed over
    monkeypatch.undo()
    first = []

    def smaller(*a):
        first.append(1)
        raise sizing.NoRoomError("no room at the size its parts fit", "bad-parameters")

    fit = bed.laid_fit_factor
    monkeypatch.setattr(printable, "_smaller", smaller)
    monkeypatch.setattr(bed, "laid_fit_factor", lambda ext, pr: fit(ext, pr) * (
        0.5 if not first else 1e3))
    cands = [choice.Candidate(f"c{k}", 4, lambda: (real, None)) for k in range(2)]
    pr = printable.make(cands, printable.Options(samples=8, ground=False))
    assert pr.candidate == "c1" and any(t.startswith("c0: not built") for t in
                                        pr.report["choice"]["tried"])


def test_a_candidate_whose_parts_shrink_below_the_floors_gives_way(monkeypatch):
    """Built parts that fit the bed only at a smaller size than sized, where the bars fall
    below the floors (the sizing's thin-bar level): the next candidate is built too and
    taken where its bars keep the floors; the report says why (random 62203 printed bars
    37 times as long as wide so, where the next candidate had 7.8 mm bars)."""
    real, build, calls = F.real(), printable._fit_and_build, []

    def fit_and_build(real, ee, plan, opts, *a):
        asm, plan, method = build(real, ee, plan, opts, *a)
        calls.append(plan.level)
        shrunk = len(calls) == 1
        return asm, replace(plan, level=3) if shrunk else plan, method

    monkeypatch.setattr(printable, "_fit_and_build", fit_and_build)
    cands = [choice.Candidate(f"c{k}", 4, lambda: (real, None)) for k in range(2)]
    pr = printable.make(cands, printable.Options(samples=8, ground=False))
    assert len(calls) == 2 and max(calls) < 3 and pr.candidate == "c1"
    assert any(t.startswith("c0: its parts fit the bed only at") and "thinner than the floors"
               in t for t in pr.report["choice"]["tried"])


def test_sizes_between_are_tried_where_the_one_the_parts_fit_at_has_no_room(monkeypatch):
    """The room is uneven in the size (stock hardware): radii at the bed's size (parts 8 %
    too large) and at 93 - 95 % of it only. The size the parts fit at (92 %) has none; the
    sizes between it and the bed's are tried before the next smaller one."""
    real = F.real()
    b = rows.bounds_of(real)
    top = bed.bed_scale(b.points, GENERIC) * b.extent
    tried = []

    def at_scale(real, b, k, *a, **kw):
        size = k * b.extent
        tried.append(size / top)
        return SimpleNamespace(size_mm=size) if size >= top * 0.9999 or \
            0.93 <= size / top <= 0.95 else None

    monkeypatch.setattr(sizing, "at_scale", at_scale)
    got = sizing.plan(real, GENERIC, F.PLA, "m3", ROD,
                      fit=lambda p: 0.92 if p.size_mm > 0.96 * top else 1.0)
    assert 0.93 <= got.size_mm / top <= 0.95
    assert min(tried) >= 0.92 * 0.999  # never below the size the parts fit at
