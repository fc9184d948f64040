"""Verification of the built parts over the cycle (:mod:`fabrication.check`): a clean assembly
passes, a part moved into another is reported, the continuous bound is a sound lower bound of
exact gaps at parameters between the samples, the joint-angle bound alone suffices."""

from __future__ import annotations

from dataclasses import replace

import fab_fixtures as F
import manifold3d as m3d
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from paraloop_core.algebra import dq, poly
from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import check, keel
from paraloop_core.linkage import loops


def group(asm, link: int) -> m3d.Manifold:
    """Everything rigid with ``link``: its printed parts and the hardware it carries."""
    return m3d.Manifold.batch_boolean(
        [p.manifold for p in asm.parts if p.link == link]
        + [h.solid for h in asm.hardware if h.link == link], m3d.OpType.Add)


def test_the_printed_loop_verifies():
    pr = F.printed()
    ver = pr.report["verification"]
    assert ver["ok"] and ver["gap_ok"] and ver["watertight"] and ver["collisions"] == 0
    assert ver["samples"] == F.SAMPLES and len(ver["pairs"]) == 15
    assert {p["name"] for p in ver["parts"]} == {p.name for p in pr.assembly.parts}
    assert all(p["watertight"] and p["pieces"] == 1 for p in ver["parts"])
    for p in ver["pairs"]:
        assert p["continuous_min_gap_mm"] <= p["min_gap_mm"] + 1e-12  # the bound <= samples
        assert p["samples"] >= F.SAMPLES
        if not p["adjacent"]:
            a, b = p["links"]
            assert p["required_gap_mm"] == pytest.approx(pr.assembly.plan.gaps[a, b])
            assert p["continuous_min_gap_mm"] >= p["required_gap_mm"]
    assert ver["min_non_adjacent_gap_mm"] == min(p["continuous_min_gap_mm"]
                                                 for p in ver["pairs"] if not p["adjacent"])
    c = pr.assembly.printer.clearance_mm
    assert ver["joint_clearance_mm"] == pytest.approx(c, abs=0.02)


def test_continuous_bound_holds_between_the_samples():
    """Exact gaps (manifold3d) of every pair of links without a common joint, at random
    parameters off the verification's samples, are at least the continuous bound."""
    pr = F.printed()
    asm = pr.assembly
    u = np.random.default_rng(7).random(40)
    poses = dq.to_matrix(loops.link_poses(asm.joint_factors, poly.param_to_t(u)))
    poses[..., :3, 3] *= asm.scale
    solids = [group(asm, i) for i in range(6)]
    checked = 0
    for p in pr.report["verification"]["pairs"]:
        if p["adjacent"]:
            continue
        a, b = p["links"]
        bound = p["continuous_min_gap_mm"]
        rel = np.linalg.inv(poses[:, a]) @ poses[:, b]
        for m in rel:
            moved = solids[b].transform([list(r) for r in m[:3]])
            assert solids[a].min_gap(moved, bound + 1.0) >= bound - 1e-6, (a, b)
            checked += 1
    assert checked == 9 * len(u)


def _moved_into(asm, mover: int, target: int):
    """``asm`` with link ``mover`` (solid and capsules) moved onto link ``target``'s bar."""
    bar = lambda i: asm.bars[i][0].mean(axis=0)  # noqa: E731
    v = bar(target) - bar(mover)
    p = asm.parts[mover]
    moved = replace(p, manifold=p.manifold.translate(tuple(v)), capsules=p.capsules + v)
    return replace(asm, parts=tuple(moved if q is p else q for q in asm.parts))


def test_a_part_moved_into_another_is_reported():
    asm = _moved_into(F.assembly("m3"), 3, 0)
    ver = check.verify(asm, samples=16)
    assert not ver["ok"] and ver["collisions"] > 0 and ver["min_gap_mm"] <= 0.0
    hit = next(p for p in ver["pairs"] if p["links"] == [0, 3])
    assert hit["colliding_samples"] > 0 and hit["max_intersection_mm3"] > 0
    assert hit["continuous_min_gap_mm"] <= 0.0


def test_a_verification_for_the_keels_takes_off_what_the_whole_one_does():
    """With ``keels`` a pair of a keeled link stops at its first sample short of its gap, and
    once one fails, the pairs that would take off no other keel are left out: the keels
    taken off are the whole verification's; a pair short of its required gap at a sample is
    refined only to prove it apart (still failing, apart)."""
    asm = F.assembly("m3")
    near = min((p for p in check.verify(asm, samples=16)["pairs"] if not p["adjacent"]),
               key=lambda p: p["min_gap_mm"])
    (a, b), need = near["links"], near["min_gap_mm"] + 1.0  # that pair short of it
    gaps = asm.plan.gaps.copy()
    gaps[a, b] = gaps[b, a] = need
    asm = replace(asm, plan=replace(asm.plan, gaps=gaps))
    whole = check.verify(asm, samples=16)
    short = next(p for p in whole["pairs"] if p["links"] == [a, b])
    assert 0.0 < short["continuous_min_gap_mm"] < need and short["min_gap_mm"] < need
    assert not whole["gap_ok"] and whole["ok"] and "partial" not in whole
    for keels in (np.eye(6)[b] * 2.0, np.eye(6)[a] + np.eye(6)[(b + 1) % 6] * 3.0,
                  np.eye(6)[(b + 1) % 6]):
        quick = check.verify(asm, samples=16, keels=list(keels))
        off = keel.in_the_way(list(keels), whole["pairs"])
        assert keel.in_the_way(list(keels), quick["pairs"]) == off
        assert quick.get("partial", False) == bool(off)
        assert len(quick["pairs"]) < 15 if off else quick["pairs"] == whole["pairs"]


def test_few_samples_are_refined_until_the_cycle_is_proven():
    ver = check.verify(F.assembly("m3"), samples=16)
    assert ver["ok"] and ver["continuous_min_gap_mm"] > 0
    counts = [p["samples"] for p in ver["pairs"]]
    assert max(counts) > min(counts) >= 16  # the cells of some pairs were split
    with pytest.raises(FabricationError) as err:
        check.verify(F.assembly("m3"), samples=4)
    assert err.value.reason == "bad-parameters"


def test_verification_without_a_speed_bound(monkeypatch):
    """Where a motion passes too close to a singular pose for a speed bound, the joint-angle
    bound alone certifies the cycle; it is sound: at least the largest sampled displacement."""
    from paraloop_core.realization import motion_bound as mbm

    jf, pts, _ = F.example_loop()
    u = (np.arange(64) + 0.5) / 64
    center = pts[4]
    chain = mbm.sound_displacement_bounds(jf, 0, 2, center, 0.3, u, None)
    assert np.array_equal(chain, mbm.chain_displacement_bounds(jf, 0, 2, center, 0.3, u))
    fine = np.linspace(0.0, 1.0, 64 * 64, endpoint=False)
    c = loops.relative_motion(jf, 0, 2)
    x = dq.transform_points(poly.evaluate(c, poly.param_to_t(fine)), center)
    x0 = dq.transform_points(poly.evaluate(c, poly.param_to_t(u)), center)
    near = np.abs(((fine[:, None] - u[None] + 0.5) % 1.0) - 0.5).argmin(axis=1)
    moved = np.linalg.norm(x - x0[near], axis=-1)
    assert moved.max() > 0.1 * chain.max() and np.all(moved <= chain[near] + 1e-12)

    def refuse(*args, **kwargs):
        raise FabricationError("too close to a singular pose", "bad-parameters")

    monkeypatch.setattr(mbm, "motion_bound", refuse)
    assert mbm.try_motion_bound(jf, 0, 2, center) is None
    ver = check.verify(F.assembly("m3"), samples=48)
    assert ver["ok"] and ver["continuous_min_gap_mm"] > 0


def _disc_piece(radius: float, half: float) -> check._Piece:
    """A 64-gon disc about the z axis, z in [-half, half]: its ball capsule and its slab."""
    solid = m3d.Manifold.cylinder(2 * half, radius, radius, 64).translate([0.0, 0.0, -half])
    return check._Piece(solid, np.zeros((1, 2, 3)), np.array([np.hypot(radius, half)]),
                        np.full(1, -1), np.array([[0.0, 0.0, 1.0, half + 1e-6]]))


def _rod_piece(p0: np.ndarray, p1: np.ndarray, r: float) -> check._Piece:
    from paraloop_core.fabrication import parts

    return check._Piece(parts.cylinder(p0, p1, r), np.array([[p0, p1]]), np.array([r]),
                        np.full(1, -1), check._no_slabs(1))


@pytest.mark.parametrize("disc_moves", [False, True])
def test_a_slab_raises_the_capsule_bound_and_stays_below_the_exact_gap(disc_moves):
    """A plate's slab (its thickness) bounds the gap far above its ball when a bar passes
    over it, and never above the exact gap (manifold3d), with the slab on either side."""
    rng = np.random.default_rng(11)
    disc = _disc_piece(40.0, 2.5)
    rods = [_rod_piece(*rng.normal(0.0, 25.0, (2, 3)) + [0.0, 0.0, 12.0], 3.0)
            for _ in range(6)]
    rots = np.tile(np.eye(4), (30, 1, 1))
    rots[:, :3, :3] = Rotation.random(30, random_state=3).as_matrix()
    rots[:, :3, 3] = rng.normal(0.0, 10.0, (30, 3))
    raised = 0
    for rod in rods:
        pa, pb = ([rod], [disc]) if disc_moves else ([disc], [rod])
        bounds = check._piece_bounds(pa, pb, rots)[0, 0]
        ball = check._capsule_gap((pa[0].caps, pa[0].radii), (pb[0].caps, pb[0].radii), rots)
        assert np.all(bounds >= ball - 1e-12)
        for m, lb in zip(rots, bounds, strict=True):
            moved = pb[0].solid.transform(check._affine(m))
            exact = pa[0].solid.min_gap(moved, max(lb, 0.0) + 1.0)
            assert exact >= lb - 1e-6
        raised += int(np.sum(bounds > ball + 5.0))
    assert raised > 20  # the slab is not idle
