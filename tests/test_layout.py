"""Laid for printing (:mod:`fabrication.layout`): support area known answers, the bed layout
of the test assembly's parts and its 3MF plates, a long part turned onto the diagonal, the
print flat's wall slack."""

from __future__ import annotations

import io
import itertools

import fab_fixtures as F
import manifold3d as m3d
import numpy as np
import pytest
import trimesh

from paraloop_core.fabrication import bed, export, flat, layout, profiles

DOWN = np.array([0.0, 0.0, -1.0])


def mesh(solid: m3d.Manifold) -> trimesh.Trimesh:
    return F.mesh_of(solid)


def box(lo, hi) -> m3d.Manifold:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return m3d.Manifold.cube(tuple(hi - lo)).translate(tuple(lo))


def test_support_known_answers():
    cube = mesh(box([0, 0, 0], [10, 10, 10]))
    assert layout.support(cube.vertices, cube.faces, DOWN) == pytest.approx((0.0, 100.0))
    # a T: stem 10 x 10 x 20 on the bed, a 30 x 10 x 5 bar on top: the bar's underside
    # beside the stem (2 x 10 x 10) hangs in the air
    t = mesh(box([0, 0, 0], [10, 10, 20]) + box([-10, 0, 20], [20, 10, 25]))
    assert layout.support(t.vertices, t.faces, DOWN) == pytest.approx((200.0, 300.0))
    # upside down, on the bar's top: nothing overhangs (the stem's end faces up)
    assert layout.support(t.vertices, t.faces, -DOWN)[0] == pytest.approx(0.0)
    # on its side (down = -y): the faces at y = 0 lie on the bed, nothing hangs
    assert layout.support(t.vertices, t.faces, [0.0, -1.0, 0.0])[0] == pytest.approx(0.0)


def test_a_ramp_from_the_bed_needs_support_above_the_first_layer():
    """A wedge resting on its 10 mm edge whose underside rises at 30 deg from the bed: the
    underside touches the first layer along that edge, and all of it above 0.3 mm needs
    support (a face is not exempt for touching the first layer at one end)."""
    a = np.radians(30.0)
    end = [40 * np.cos(a), 0, 40 * np.sin(a)]
    side = [[0, 0, 0], end, [end[0], 0, end[2] + 5]]
    m = mesh(m3d.Manifold.hull_points([list(p) for p in np.vstack([side, np.add(side,
                                                                                [0, 10, 0])])]))
    area, _ = layout.support(m.vertices, m.faces, DOWN)
    assert area == pytest.approx(10 * (40 - layout.FIRST_LAYER_MM / np.sin(a)), rel=1e-6)


@pytest.mark.parametrize(("tilt", "needs"), [(30.0, True), (60.0, False)])
def test_support_at_the_overhang_limit(tilt, needs):
    """A slab 10 mm deep whose underside rises ``tilt`` deg from the horizontal, its low end
    on a 2 mm foot: the underside needs support below 45 deg from the horizontal (its normal
    within 45 deg of straight down), not above."""
    a = np.radians(tilt)
    rise = 40 * np.tan(a)
    side = [[0, 0, 5], [40, 0, 5 + rise], [0, 0, 10 + rise], [40, 0, 10 + rise]]
    slab = m3d.Manifold.hull_points([list(p) for p in np.vstack([side, np.add(side,
                                                                              [0, 10, 0])])])
    m = mesh(slab + box([0, 0, 0], [2, 10, 5.5 + 2 * np.tan(a)]))  # into the slab
    area, downward = layout.support(m.vertices, m.faces, DOWN)
    sloped = 10 * 38 / np.cos(a)  # the underside beside the foot
    assert area == pytest.approx(sloped if needs else 0.0, rel=1e-6, abs=1e-9)
    assert downward == pytest.approx(sloped + 20.0, rel=1e-6)  # and the foot on the bed


@pytest.fixture(scope="module")
def laid():
    asm = F.assembly("printed-pin")
    meshes = export.part_meshes(asm)
    return asm, meshes, layout.bed_layout(meshes, export.downs(asm), asm.printer.bed_mm)


def test_bed_layout_keeps_parts_on_the_bed(laid):
    asm, meshes, placements = laid
    bed_mm = np.asarray(asm.printer.bed_mm)
    assert sorted(p.name for p in placements) == sorted(meshes)
    boxes = {}
    for p in placements:
        m = meshes[p.name].copy().apply_transform(p.transform)
        assert np.allclose(p.transform[:3, :3] @ p.transform[:3, :3].T, np.eye(3))  # rigid
        assert m.volume == pytest.approx(meshes[p.name].volume, rel=1e-9)
        lo, hi = m.bounds
        assert lo[2] == pytest.approx(0.0, abs=1e-6) and np.all(lo >= -1e-6)
        assert np.all(hi <= bed_mm + 1e-6), p.name
        assert hi[2] == pytest.approx(p.height_mm, rel=1e-9)
        on_bed = m.area_faces[(m.triangles[:, :, 2].max(1) < 0.05) &
                              (m.face_normals[:, 2] < -1 + 1e-6)].sum()
        assert on_bed == pytest.approx(p.contact_mm2, rel=1e-6, abs=1e-9)
        part = next(q for q in asm.parts if q.name == p.name)
        # links cut flat stand on their flat, caps on their closed end (a pin lies on its
        # side: a polygon's edge, no area)
        if part.role == "cap" or (part.role == "link" and asm.slack[part.link] >= 0):
            assert on_bed > 0, p.name
        boxes.setdefault(p.plate, []).append((lo[:2], hi[:2]))
    for plate in boxes.values():  # footprints on one plate do not overlap
        for (lo_a, hi_a), (lo_b, hi_b) in itertools.combinations(plate, 2):
            assert np.any(hi_a <= lo_b + 1e-6) or np.any(hi_b <= lo_a + 1e-6)
    entry = layout.layout_entry(placements, asm.printer.bed_mm)
    assert entry["plates"] == 1 + max(boxes) and all(p["fits_bed"] for p in entry["parts"])
    for p in entry["parts"]:
        assert 0.0 <= p["support_share"] <= 1.0


def test_plates_hold_the_parts_laid(laid):
    asm, meshes, placements = laid
    files = dict(layout.plate_files(meshes, placements))
    n = 1 + max(p.plate for p in placements)
    assert sorted(files) == ["paraloop.3mf"] + [f"paraloop_plate{k}.3mf" for k in range(2, n + 1)]
    seen = {}
    for data in files.values():
        scene = trimesh.load(io.BytesIO(data), file_type="3mf")
        for node in scene.graph.nodes_geometry:
            tf, geom = scene.graph[node]
            seen[node] = scene.geometry[geom].copy().apply_transform(tf)
    assert sorted(seen) == sorted(meshes)
    for p in placements:
        assert seen[p.name].bounds[0][2] == pytest.approx(0.0, abs=1e-5)
        assert seen[p.name].volume == pytest.approx(meshes[p.name].volume, rel=1e-5)


def test_pins_lie_on_their_side_and_caps_on_their_end(laid):
    asm, meshes, placements = laid
    for p in placements:
        part = next(q for q in asm.parts if q.name == p.name)
        j = asm.joints[part.joint[0]]
        axis = p.transform[:3, :3] @ j.w
        if part.role == "pin":
            assert abs(axis[2]) < 1e-9  # layers along the pin
        elif part.role == "cap":
            assert abs(axis[2]) == pytest.approx(1.0)


def test_long_part_lies_diagonally_on_the_bed():
    """A 300 mm bar does not fit a 250 x 210 bed square-on: the layout turns it onto the
    diagonal (still flat, inside the bed), as bed.fits_bed promised."""
    bar = trimesh.creation.box([300.0, 12.0, 8.0])
    bar.apply_transform(trimesh.transformations.rotation_matrix(0.3, [0.2, 0.5, 1.0]))
    down = bar.face_normals[np.argmax(bar.area_faces * (bar.face_normals @ [0.2, 0.5, 1.0]))]
    bed_mm = (250.0, 210.0, 210.0)
    assert bed.fits_bed(np.array([[300.0, 12.0, 8.0]]), profiles.Printer("t", bed_mm))[0]
    (place,) = layout.bed_layout({"bar": bar}, {"bar": down}, bed_mm)
    m = bar.copy().apply_transform(place.transform)
    assert m.bounds[0, 2] == pytest.approx(0.0, abs=1e-6)
    assert m.extents[2] == pytest.approx(np.ptp(bar.vertices @ down), abs=1e-6)  # on it
    assert np.all(m.bounds[0] >= -1e-6) and np.all(m.bounds[1] <= np.array(bed_mm) + 1e-6)


def test_wall_slack_is_the_room_under_each_bore():
    """The slack of a print flat: the least distance from the flat to a held bore's wall (the
    hardware sits outside the bosses: nothing else to keep); the chosen flats of the test
    assembly are reported with it, and a flat moved in by the slack and a hair more breaks
    into a wall."""
    asm = F.assembly("m3")
    wall = asm.printer.wall_mm
    for p in asm.links:
        i = p.link
        sides = [(asm.joints[i], False), (asm.joints[(i - 1) % 6], True)]
        level = float(np.max(asm.bars[i].reshape(-1, 3) @ p.down)) + \
            asm.plan.radii[i] * np.sqrt(3) / 2
        slack = flat.wall_slack(p.down, level, sides, wall)
        assert slack == pytest.approx(asm.slack[i])
        room = []
        for j, up in sides:
            bore = j.bore[1 if up else 0]
            # the deepest point of the wall's cylinder at each end of the boss: across the
            # axis, measured on a dense ring (not the formula under test)
            phi = np.linspace(0.0, 2 * np.pi, 3601)
            a = np.cross(j.w, [1.0, 0, 0] if abs(j.w[0]) < 0.9 else [0, 1.0, 0])
            a /= np.linalg.norm(a)
            ring = np.outer(np.cos(phi), a) + np.outer(np.sin(phi), np.cross(j.w, a))
            reach = float((ring @ p.down).max()) * (bore + wall + flat.WALL_ROOM_MM)
            room += [level - p.down @ j.at(s) - reach for s in (j.upper if up else j.lower)]
        assert slack == pytest.approx(min(room), abs=1e-5)  # the ends of the bores decide
        assert flat.wall_slack(p.down, level - slack - 1e-3, sides, wall) < 0


@pytest.mark.parametrize("target", [0.3, 0.0, -0.1, -0.19, -0.21, -0.5, -3.0])
def test_a_flat_short_of_the_full_room_still_keeps_the_least_room(target):
    """A print flat keeping less room than :data:`flat.WALL_ROOM_MM` beyond the bores' walls
    but at least :data:`flat.MIN_ROOM_MM` still lies on the bar's face; one keeping less is cut
    deeper (:func:`flat.lift`), exactly so far that the least room is kept."""
    asm = F.assembly("m3")
    wall = asm.printer.wall_mm
    p = asm.links[0]
    sides = [(asm.joints[0], False), (asm.joints[5], True)]
    level = float(np.max(asm.bars[0].reshape(-1, 3) @ p.down))
    level += flat.wall_slack(p.down, level, sides, wall) * -1.0 + target  # slack = target
    s = flat.wall_slack(p.down, level, sides, wall)
    assert s == pytest.approx(target, abs=1e-9)
    least = flat.MIN_ROOM_MM - flat.WALL_ROOM_MM
    assert flat.lies_flat(s) == (target >= least) and (flat.lift(s) == 0.0) == flat.lies_flat(s)
    kept = flat.wall_slack(p.down, level + flat.lift(s), sides, wall)
    assert kept == pytest.approx(max(target, least), abs=1e-9)
