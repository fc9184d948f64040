"""Printable parts: watertight manifolds, pins in bores with the clearance, refused parameters."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import trimesh
from conftest import random_rotation_factors

from paraloop_core.algebra import dq, factor, poly
from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import parts
from paraloop_core.linkage import loops
from paraloop_core.realization import realize


@functools.lru_cache(maxsize=1)
def example_loop() -> tuple[np.ndarray, np.ndarray, float]:
    """A realized loop ``(joint_factors, points, radius)`` of a random generic cubic, rotated
    so that its base link's axis A_0 points down (the grounding column goes there)."""
    c = poly.from_factors(random_rotation_factors(np.random.default_rng(1)))
    jf = loops.loop_joint_factors(factor.all_factorizations_batch(c).factors)[4]
    r = realize.realize(jf, d_fraction=0.08, rho_fraction=0.25)
    d = r.points[1] - r.points[2]
    d /= np.linalg.norm(d)
    axis = np.cross(d, [0.0, 0.0, -1.0])
    g = dq.rotation_about_line(axis / np.linalg.norm(axis), np.zeros(3),
                               np.arccos(np.clip(-d[2], -1.0, 1.0)))
    jf2 = dq.mul(dq.mul(g, r.joint_factors), dq.conj(g))
    return jf2, dq.transform_points(g, r.points), r.radius


@functools.lru_cache(maxsize=2)
def example_assembly(print_in_place: bool = False) -> parts.Assembly:
    jf, pts, radius = example_loop()
    return parts.build_assembly(jf, pts, radius, parts.PartSpec(print_in_place=print_in_place))


def as_trimesh(man) -> trimesh.Trimesh:
    mesh = man.to_mesh()
    return trimesh.Trimesh(mesh.vert_properties[:, :3], mesh.tri_verts, process=True)


@pytest.mark.parametrize("pip", [False, True])
def test_parts_are_watertight_manifolds(pip):
    asm = example_assembly(pip)
    assert len(asm.parts) == 6
    for p in asm.parts:
        assert p.manifold.status() == parts.m3d.Error.NoError
        tm = as_trimesh(p.manifold)
        assert tm.is_watertight and tm.is_winding_consistent, p.name
        assert tm.volume > 0
        # each part lies in the union of its bounding capsules (broad phase of verification)
        v = tm.vertices
        d = np.min([parts.point_segment_distance(v, c[0], c[1]) - r
                    for c, r in zip(p.capsules, p.radii, strict=True)], axis=0)
        assert d.max() <= 1e-3


@pytest.mark.parametrize("pip", [False, True])
def test_pins_fit_bores_with_clearance(pip):
    asm = example_assembly(pip)
    spec = asm.spec
    poly_err = (spec.pin_radius_mm + spec.clearance_mm) * (1 - np.cos(np.pi / spec.segments))
    for j, z in enumerate(asm.zones):
        lo, up = asm.parts[j], asm.parts[(j + 1) % 6]
        # the pin of the lower link reaches through the upper link's boss (without
        # print-in-place into a blind bore, to 2 c short of its far end) ...
        tip = z.length + spec.boss_length_mm - (0.0 if pip else 2 * spec.clearance_mm)
        boss_up = parts.cylinder(z.at(z.length / 2 + spec.clearance_mm), z.at(tip - 1e-3),
                                 spec.pin_radius_mm * 0.99, spec.segments)
        assert (lo.manifold ^ boss_up).volume() == pytest.approx(boss_up.volume(), rel=1e-3)
        # ... without touching it: the gap is the clearance (up to the polygon error)
        gap = lo.manifold.min_gap(up.manifold, 5.0)
        assert spec.clearance_mm - poly_err - 1e-6 <= gap <= spec.clearance_mm + 1e-6
        assert (lo.manifold ^ up.manifold).volume() < 1e-9


def test_rotated_parts_stay_clear_at_joint():
    """Turning a joint keeps the pin in its bore: the hardware is a solid of revolution."""
    asm = example_assembly(False)
    z = asm.zones[2]
    lo, up = asm.parts[2], asm.parts[3]
    for angle in (0.4, 1.7, 3.0):
        turn = dq.to_matrix(dq.rotation_about_line(z.w, z.origin, angle))
        moved = up.manifold.transform([list(r) for r in turn[:3]])
        w = parts.zone_solid(z, asm.spec.segments)
        assert (lo.manifold ^ w ^ moved).volume() < 1e-9


def test_scale_sets_longest_extent():
    jf, pts, radius = example_loop()
    s = parts.design_scale(pts, 200.0)
    assert np.ptp(pts * s, axis=0).max() == pytest.approx(200.0)


@pytest.mark.parametrize("kwargs", [
    {"clearance_mm": -0.1}, {"size_mm": 0.0}, {"size_mm": -5.0},
    {"pin_radius_mm": 50.0}, {"rho_mm": 0.0}, {"boss_length_mm": -1.0}, {"segments": 3},
])
def test_bad_parameters_refused(kwargs):
    jf, pts, radius = example_loop()
    with pytest.raises(FabricationError) as err:
        parts.build_assembly(jf, pts, radius, parts.PartSpec(**kwargs))
    assert err.value.reason == "bad-parameters"
    assert isinstance(err.value, ValueError)


def test_too_small_size_says_what_to_do():
    jf, pts, radius = example_loop()
    with pytest.raises(FabricationError, match="size of at least"):
        parts.build_assembly(jf, pts, radius, parts.PartSpec(size_mm=10.0))


def _lean_points(lean_lower: bool) -> np.ndarray:
    """A polyline whose joint 0 pin runs from E_0 = (0,0,0) to S_1 = (0,0,10) (mm): link 1's
    bar leans back from S_1 over the pin, link 0's bar leans away or (``lean_lower``) over it."""
    s0 = [0.0, -30.0, 16.0] if lean_lower else [0.0, -30.0, -20.0]
    # the other bars leave their pins at right angles
    return np.array([s0, [0, 0, 0], [0, 0, 10], [7, 0, 0], [60, 0, 2], [60, 30, 2],
                     [60, 60, 2], [30, 60, 2], [0, 60, 2], [0, 90, 2], [-30, 90, 2],
                     [-30, 0, 2]], float)


SPEC = parts.resolve_spec(parts.PartSpec(size_mm=90.0, rho_mm=1.0, boss_radius_mm=3.3,
                                         pin_radius_mm=1.0), 1.0, 1.0)


def test_split_moves_away_from_a_bar_that_leans_back():
    jf = example_loop()[0]
    one = parts.joint_zones(jf, _lean_points(False), SPEC)[0]
    assert one.notch == (0.0, 0.0) and one.split < 5.0 - 1.0  # towards E_0, off the middle
    # link 1's bar material within the zone cut's radius stays above the split (sampled)
    d = np.array([7.0, 0.0, -10.0]) / np.linalg.norm([7.0, 0.0, -10.0])
    lam = np.linspace(0.0, 12.2, 4001)[:, None]
    phi = np.linspace(0.0, 2.0 * np.pi, 73)[:, None]
    disc = np.cos(phi) * [0.0, 1.0, 0.0] + np.sin(phi) * np.cross(d, [0.0, 1.0, 0.0])
    surface = (np.array([0, 0, 10.0]) + lam * d)[:, None] + SPEC.rho_mm * disc[None]
    near = np.hypot(surface[..., 0], surface[..., 1]) < one.radius + one.gap + one.eps
    assert near.any()
    assert surface[..., 2][near].min() >= one.split + one.gap / 2 + one.eps - 1e-9
    both = parts.joint_zones(jf, _lean_points(True), SPEC)[0]
    assert both.notch[0] > 0 and both.notch[1] > 0  # no split clears both: the middle of it
    assert both.notch[0] == pytest.approx(both.notch[1])


def test_notched_bars_keep_the_clearance():
    """Both bars lean over the pin, so the zone notches them: what is left of each keeps the
    clearance c from the neighbour's boss and its end face (it kept only the zone margin eps,
    0.018 mm on random design 0, before)."""
    spec = parts.PartSpec(size_mm=90.0, rho_mm=1.0, boss_radius_mm=3.3, pin_radius_mm=1.0)
    asm = parts.build_assembly(example_loop()[0], _lean_points(True), 1.0, spec)
    assert min(asm.zones[0].notch) > 0
    poly_err = 3.7 * (1.0 - np.cos(np.pi / asm.spec.segments))
    gap = asm.parts[0].manifold.min_gap(asm.parts[1].manifold, 2.0)
    assert gap >= asm.spec.clearance_mm - 2 * poly_err


@pytest.mark.parametrize("lean_lower", [False, True])
def test_hardware_fits_at_a_moved_split(lean_lower):
    """Pin in bore and boss ends keep the clearance c wherever the split lies."""
    z = parts.joint_zones(example_loop()[0], _lean_points(lean_lower), SPEC)[0]
    solid = {}
    for upper in (False, True):
        pieces = parts._hardware(z, SPEC, upper)
        body = parts.m3d.Manifold.batch_boolean(
            [parts.cylinder(p0, p1, r, 96) for p0, p1, r, bore in pieces if not bore],
            parts.m3d.OpType.Add)
        for p0, p1, r, bore in pieces:
            if bore:
                body = body - parts.cylinder(p0, p1, r, 96)
        solid[upper] = body
    assert (solid[False] ^ solid[True]).is_empty()
    gap = solid[False].min_gap(solid[True], 1.0)
    assert SPEC.clearance_mm * 0.95 <= gap <= SPEC.clearance_mm + 1e-6


def test_loose_shards_are_dropped_and_a_severed_link_is_refused():
    hub = parts.cylinder(np.zeros(3), np.array([0.0, 0.0, 5.0]), 3.0, 48)
    shard = parts.m3d.Manifold.cube((1.0, 1.0, 1.0)).translate((20.0, 0.0, 0.0))
    kept = parts._joined(hub + shard, [hub], 0)
    assert len(kept.decompose()) == 1 and kept.volume() == pytest.approx(hub.volume())
    # the hardware of the two joints in separate pieces: a link that would fall apart
    other = hub.translate((0.0, 0.0, 40.0))
    with pytest.raises(FabricationError, match="link 4 falls apart"):
        parts._joined(hub + other + shard, [hub, other], 4)


def test_a_bar_along_its_pin_stays_on_its_boss():
    """A bar leaving its boss along the pin's axis (tv8's link 4 nearly does): the bore is
    blind, so it does not cut the bar off its boss."""
    pts = _lean_points(True)
    pts[9] = [-30.0, 60.0, 2.0]  # E_4 on the axis of joint 3's pin E_3 S_4
    pts[10:] = [[-60.0, 90.0, 2.0], [-90.0, 60.0, 2.0]]  # link 5 at right angles to its pin
    spec = parts.PartSpec(size_mm=90.0, rho_mm=1.0, boss_radius_mm=3.3, pin_radius_mm=1.0)
    asm = parts.build_assembly(example_loop()[0], pts, 1.0, spec)
    assert all(len(p.manifold.decompose()) == 1 for p in asm.parts)
