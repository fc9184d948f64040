"""The printed parts (:mod:`fabrication.parts`, built by :mod:`assembly`): valid one-piece
solids inside their capsules, flat on the bed, bores with their walls, plain bores and
flat faces for the hardware outside, joints that turn without touching."""

from __future__ import annotations

import fab_fixtures as F
import manifold3d as m3d
import numpy as np
import pytest

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import (
    check,
    flat,
    keel,
    layout,
    parts,
    profiles,
    sizing,
    stiffness,
)
from paraloop_core.fabrication.assembly import Assembly

ASSEMBLIES = ["m3", "printed-pin", "grounded"]


def assembly_of(which: str) -> Assembly:
    return F.printed().assembly if which == "grounded" else F.assembly(which)


def polygon_error(radius: float) -> float:
    """How far inside its radius a round solid's polygon (parts.SEGMENTS sides) reaches."""
    return radius * (1.0 - np.cos(np.pi / parts.SEGMENTS))


@pytest.mark.parametrize("which", ASSEMBLIES)
def test_parts_are_valid_watertight_one_piece_solids(which):
    asm = assembly_of(which)
    roles = [p.role for p in asm.parts]
    assert roles[:6] == ["link"] * 6 and [p.link for p in asm.links] == list(range(6))
    if which == "printed-pin":
        assert roles.count("pin") == 6 and roles.count("cap") == 6
    if which == "grounded":
        # the plate, the rod cap and a cap per dowel
        dowels = sum(j.kind == "dowel" for j in asm.joints)
        assert roles.count("base") == 1 and roles.count("cap") == 1 + dowels
    for p in asm.parts:
        assert p.manifold.status() == m3d.Error.NoError and not p.manifold.is_empty()
        tm = F.mesh_of(p.manifold)
        assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0, p.name
        assert len(p.manifold.decompose()) == 1, p.name
        assert not parts.pinched(p.manifold), p.name


@pytest.mark.parametrize("which", ASSEMBLIES)
def test_every_vertex_lies_in_its_capsules(which):
    """The verification's broad phase takes each part (and piece of hardware) to lie in the
    union of its capsules: no vertex outside by more than float32 rounding."""
    asm = assembly_of(which)
    solids = [(p.name, p.manifold, p.capsules, p.radii) for p in asm.parts]
    solids += [(h.role, h.solid, h.capsule[None], np.array([h.radius])) for h in asm.hardware]
    for name, solid, caps, radii in solids:
        v = F.mesh_of(solid).vertices
        out = np.min([F.point_segment(v, c[0], c[1]) - r for c, r in zip(caps, radii,
                                                                         strict=True)], axis=0)
        assert out.max() <= F.float32_slack(v), name


@pytest.mark.parametrize("which", ["m3", "grounded"])
def test_print_flat_is_the_lowest_face(which):
    """Each link is cut at its bar's down face, or deeper by :func:`flat.lift` where a bore
    needs it: no material beyond that plane, the faces on it face the bed, and laid on the
    bed they are where it stands: at least the bar's face, or the bosses' cut faces."""
    asm = assembly_of(which)
    for p in asm.links:
        i = p.link
        r = float(asm.plan.radii[i])
        bar = asm.bars[i]
        level = float(np.max(bar.reshape(-1, 3) @ p.down)) + r * np.sqrt(3) / 2
        level += flat.lift(asm.slack[i])
        tm = F.mesh_of(p.manifold)
        h = tm.vertices @ p.down
        assert h.max() == pytest.approx(level, abs=F.float32_slack(tm.vertices))
        on = (tm.triangles @ p.down).min(axis=1) > level - 1e-4
        face = tm.area_faces[on].sum()
        # the faces on the plane face the bed; a sliver of the float32 mesh may tilt (one of
        # 3e-5 mm^2 tilted 8.5 deg under another BLAS kernel): its area is nothing
        tilted = on & (tm.face_normals @ p.down <= 0.99)
        assert tm.area_faces[tilted].sum() <= 1e-4 * face
        length = float(np.linalg.norm(bar[0][1] - bar[0][0]))
        if flat.lies_flat(asm.slack[i]):
            assert face >= r * length * 0.9  # a hexagon's side is its corner radius
        else:  # on the bosses' cut faces: each keeps at least a wall's width
            assert face >= asm.printer.wall_mm ** 2, (p.name, face)
        rot = layout.to_bed(p.down)
        laid = tm.vertices @ rot[:3, :3].T
        assert laid[:, 2].min() == pytest.approx(-level, abs=F.float32_slack(tm.vertices))
        assert layout.contact_area(tm, rot) == pytest.approx(face, rel=1e-3)  # slivers


def _sides(asm: Assembly, i: int):
    """Link i's joints: ``(joint, upper side)``."""
    return [(asm.joints[i], False), (asm.joints[(i - 1) % 6], True)]


def _radial(j, phi: np.ndarray) -> np.ndarray:
    a = np.cross(j.w, [1.0, 0, 0] if abs(j.w[0]) < 0.9 else [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(j.w, a)
    return np.cos(phi)[:, None] * a + np.sin(phi)[:, None] * b


@pytest.mark.parametrize("which", ASSEMBLIES)
def test_bores_keep_the_profile_wall(which):
    """Rays from the axis across each bore's held length, every 22.5 deg
    and straight towards the print flat: the bore is clear to its radius, and the material
    around it is at least the printer's wall thick."""
    asm = assembly_of(which)
    wall = asm.printer.wall_mm
    for p in asm.links:
        tris = F.mesh_of(p.manifold).triangles
        for j, upper in _sides(asm, p.link):
            s0, s1 = j.upper if upper else j.lower
            # where the axle is: a dowel's blind bore ends at its floor
            (axle,) = [q for q in j.pieces if q.role in ("screw", "pin", "rod", "dowel")]
            held = (max(s0, axle.s0), min(s1, axle.s1))
            bore = j.bore[1 if upper else 0]
            down = p.down - (p.down @ j.w) * j.w
            dirs = np.vstack([_radial(j, np.arange(16) * np.pi / 8 + 0.0123),
                              down / np.linalg.norm(down)])
            for s in np.linspace(held[0] + 0.02, held[1] - 0.02, 5):
                for d in dirs:
                    hits = F.ray_hits(tris, j.at(s), d)
                    assert hits[0] >= bore - polygon_error(bore) - 1e-4, (p.name, j.index)
                    assert hits[1] - hits[0] >= wall - polygon_error(j.boss_radius) - 1e-4, (
                        p.name, j.index, s, hits[:2])


def test_screw_bores_run_plain_to_faces_the_washers_bear_on():
    """Screw joints: the hardware sits outside the bosses, so each bore is plain to the boss's
    outer face (no counterbore or nut trap) and that face is where the material ends along
    the axis, all round the bore (the washer under the head or the nut bears on it)."""
    asm = F.assembly("m3")
    phi = np.arange(24) * np.pi / 12 + 0.0123
    for j in asm.joints:
        lower, upper = asm.parts[j.index], asm.parts[(j.index + 1) % 6]
        if j.kind == "dowel":  # test_dowel_bores_are_blind_where_the_bar_runs_on
            continue
        for part, upper_side in ((lower, False), (upper, True)):
            tris = F.mesh_of(part.manifold).triangles
            bore = j.bore[1 if upper_side else 0]
            face = j.upper[1] if upper_side else j.lower[0]
            out = j.w if upper_side else -j.w
            for s in (face - 0.3 * out @ j.w, 0.5 * sum(j.upper if upper_side else j.lower)):
                first = np.array([F.ray_hits(tris, j.at(s), d)[0] for d in _radial(j, phi)])
                assert bore - polygon_error(bore) - 1e-4 <= first.min(), (part.name, j.index)
                assert first.max() <= bore + 1e-4, (part.name, j.index, s)
            ring = bore + 0.5 * asm.printer.wall_mm  # inside what the print flat keeps
            for d in _radial(j, phi[::3]):
                start = j.at(face) - 0.5 * out + ring * d  # inside the wall, under the face
                assert F.ray_hits(tris, start, out)[0] == pytest.approx(0.5, abs=1e-3), (
                    part.name, j.index)


def test_dowel_bores_are_blind_where_the_bar_runs_on():
    """A dowel joint (its holding link's bar runs on past the boss): from inside the holding
    link's bore, along the axis outwards, material begins at the dowel's end (the blind
    floor) and goes on at least the printer's wall: nothing is cut through the bar there."""
    asm = F.assembly("m3")
    dowels = [j for j in asm.joints if j.kind == "dowel"]
    assert dowels, "the fixture's loop has a bar leaving along a joint axis"
    for j in dowels:
        side = j.rod_side
        part = asm.parts[(j.index + side) % 6]
        (axle,) = [q for q in j.pieces if q.role == "dowel"]
        out = j.w if side == 1 else -j.w
        end = axle.s1 if side == 1 else axle.s0
        start = j.at(end - 1.0 * (out @ j.w))  # 1 mm inside the bore
        hits = F.ray_hits(F.mesh_of(part.manifold).triangles, start, out)
        assert hits[0] == pytest.approx(1.0, abs=1e-3), (part.name, j.index)
        assert len(hits) == 1 or hits[1] - hits[0] >= asm.printer.wall_mm, (part.name, hits)
        # its cap, on the other end: from inside its hole outwards, a floor of more than the
        # printer's wall over the dowel's end (the hole's cut reaches a little past that end)
        (cap,) = [p for p in asm.parts if p.name == f"dowel_cap_{j.index}"]
        tip = axle.s0 if side == 1 else axle.s1
        hits = F.ray_hits(F.mesh_of(cap.manifold).triangles, j.at(tip + 1.0 * (out @ j.w)),
                          -out)
        assert len(hits) == 2 and hits[0] == pytest.approx(1.0, abs=parts.EPS_MM + 1e-3)
        assert hits[1] - hits[0] >= asm.printer.wall_mm + 0.2, (cap.name, hits)


@pytest.mark.parametrize("which", ASSEMBLIES)
def test_hardware_and_pieces_fit_their_holes(which):
    """No printed part meets the hardware or a printed piece of its joints (a pin cap is a
    press fit on its pin, by design), and two links of one joint keep the clearance. A rod or
    dowel is pressed into its holding link's bore of its own size: the two polygons share
    their faces, and the boolean's slivers there may not exceed 0.2 mm^3 (a real interference
    of 0.01 mm over 10 mm of a 3 mm dowel is 1 mm^3)."""
    asm = assembly_of(which)
    c = asm.printer.clearance_mm
    for j in asm.joints:
        links = [asm.parts[j.index].manifold, asm.parts[(j.index + 1) % 6].manifold]
        others = [(h.solid, h.role) for h in asm.hardware if h.joint == j.index]
        others += [(p.manifold, p.role) for p in asm.parts[6:] if p.joint[0] == j.index]
        for k, link in enumerate(links):
            for o, role in others:
                pressed = role in ("dowel", "rod") and j.rod_side == k
                assert (link ^ o).volume() < (0.2 if pressed else 1e-6), (j.index, role)
        gap = links[0].min_gap(links[1], 2.0)
        assert c - polygon_error(j.reach + c) - 1e-4 <= gap <= max(c, j.gap) + 1e-4, j.index


def test_printed_pin_runs_through_both_bores():
    asm = F.assembly("printed-pin")
    for j in asm.joints:
        pin = next(p for p in asm.parts if p.role == "pin" and p.joint[0] == j.index)
        cap = next(p for p in asm.parts if p.role == "cap" and p.joint[0] == j.index)
        for link, (s0, s1) in ((asm.parts[j.index], j.lower),
                               (asm.parts[(j.index + 1) % 6], j.upper)):
            # a slim cylinder along the bore over the boss's length lies in the pin
            core = parts.cylinder(j.at(s0), j.at(s1), 0.9 * profiles.PRINTED_PIN_D_MM / 2)
            assert (pin.manifold ^ core).volume() == pytest.approx(core.volume(), rel=1e-6)
            radial = j.bore[0] - profiles.PRINTED_PIN_D_MM / 2
            gap = pin.manifold.min_gap(link.manifold, 2.0)
            assert radial - polygon_error(j.bore[0]) - 1e-4 <= gap <= radial + 1e-4
        # the cap presses on the pin's end (interference), clear of link j+1's boss
        assert (cap.manifold ^ pin.manifold).volume() > 0
        assert cap.manifold.min_gap(asm.parts[(j.index + 1) % 6].manifold, 2.0) >= \
            asm.printer.clearance_mm - 1e-4


@pytest.mark.parametrize("which", ["m3", "printed-pin"])
def test_links_turn_about_their_joint_without_touching(which):
    """Inside the joint zone both links are solids of revolution about the axis on their own
    sides of the split: turning one about the axis never makes them meet there."""
    asm = assembly_of(which)
    for j in asm.joints:
        lo, up = asm.parts[j.index].manifold, asm.parts[(j.index + 1) % 6].manifold
        w = check.zone(asm, j.index)
        for angle in (0.4, 1.7, 3.0, 4.4):
            turn = _rotation(j.w, j.origin, angle)
            moved = up.transform([list(r) for r in turn[:3]])
            assert (lo ^ w ^ moved).volume() < 1e-9, (j.index, angle)


def _rotation(axis: np.ndarray, point: np.ndarray, angle: float) -> np.ndarray:
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rot = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = rot, point - rot @ point
    return m


def test_hex_bar_is_a_regular_hexagon_flat_on_down():
    p0, p1 = np.array([1.0, 2.0, 3.0]), np.array([41.0, -8.0, 23.0])
    down = np.array([0.3, 0.9, -0.2])
    bar = parts.hex_bar(p0, p1, 5.0, down)
    length = float(np.linalg.norm(p1 - p0))
    assert bar.volume() == pytest.approx(stiffness.hex_area(5.0) * length, rel=1e-6)
    tm = F.mesh_of(bar)
    u = (p1 - p0) / length
    n = down - (down @ u) * u
    n /= np.linalg.norm(n)
    # the face furthest along down is at the apothem and faces that way
    assert (tm.vertices @ n).max() - p0 @ n == pytest.approx(5.0 * sizing.APOTHEM, rel=1e-6)
    assert np.max(tm.face_normals @ n) == pytest.approx(1.0, abs=1e-6)


def test_loose_shards_are_dropped_and_a_severed_link_is_refused():
    hub = parts.cylinder(np.zeros(3), np.array([0.0, 0.0, 5.0]), 3.0, 48)
    shard = m3d.Manifold.cube((1.0, 1.0, 1.0)).translate((20.0, 0.0, 0.0))
    kept = parts._one_piece(hub + shard, 0)
    assert len(kept.decompose()) == 1 and kept.volume() == pytest.approx(hub.volume())
    other = hub.translate((0.0, 0.0, 40.0))  # two joints' halves in pieces: falls apart
    with pytest.raises(FabricationError, match="link 4 falls apart") as err:
        parts._one_piece(hub + other + shard, 4)
    assert err.value.reason == "falls-apart"
    with pytest.raises(FabricationError) as err:
        parts._one_piece(m3d.Manifold(), 1)
    assert err.value.reason == "not-watertight"


def test_body_capsules_hold_a_body():
    body = m3d.Manifold.cube((30.0, 4.0, 6.0), True).rotate((10.0, 20.0, 30.0)).translate(
        (5.0, -3.0, 100.0))
    caps = parts.principal_capsules(body, pieces=8)
    assert len(caps) <= 8
    v = F.mesh_of(body).vertices
    out = np.min([F.point_segment(v, a, b) - r for a, b, r, _ in caps], axis=0)
    assert out.max() <= 0.0


@pytest.mark.parametrize("lift", [1.0, 4.0])
def test_a_lifted_link_lies_on_its_keel(lift):
    """A link cut ``lift`` mm below its bar's face (a bore needs the room) gets a keel down to
    that cut: its material stays in its capsules, the cut is its lowest face, it lies on a
    strip about twice (wide keel) or once (narrow) as wide as the bar's face along the bar,
    and it needs far less support than the same link without the keel (whose bar prints
    over support)."""
    asm = F.assembly("m3")
    i = 0
    p, bar = asm.links[i], asm.bars[i]
    r = float(asm.plan.radii[i])
    level = float(np.max(bar.reshape(-1, 3) @ p.down)) + r * np.sqrt(3) / 2 + lift
    rot = layout.to_bed(p.down)
    length = float(np.linalg.norm(bar[0][1] - bar[0][0]))
    built, contact, share = {}, {}, {}
    for k in (keel.WIDE, keel.NARROW, keel.NONE):
        part = parts.link_part(i, bar, r, p.down, asm.joints, asm.printer.clearance_mm,
                               lift=lift, keel_level=k)
        tm = F.mesh_of(part.manifold)
        v = tm.vertices
        out = np.min([F.point_segment(v, c[0], c[1]) - rad
                      for c, rad in zip(part.capsules, part.radii, strict=True)], axis=0)
        assert out.max() <= F.float32_slack(v), k
        if k != keel.NONE:  # (the plain link's bosses need not reach this test's cut)
            assert (v @ p.down).max() == pytest.approx(level, abs=F.float32_slack(v))
        built[k], contact[k] = part, layout.contact_area(tm, rot)
        support, downward = layout.support(v, tm.faces, p.down)
        share[k] = support / downward
    assert built[keel.WIDE].keel_mm == built[keel.NARROW].keel_mm == lift
    assert built[keel.NONE].keel_mm == 0.0
    # the keel's face, less the joint zones; (what support is left: the round bosses'
    # undersides beside the keel)
    assert contact[keel.WIDE] >= 1.4 * r * length and contact[keel.NARROW] >= 0.6 * r * length
    assert contact[keel.NONE] < 0.2 * r * length
    assert max(share[keel.WIDE], share[keel.NARROW]) <= 0.1 and share[keel.NONE] >= 0.2
