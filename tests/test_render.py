"""The guide's renderer: coverage against brute force, z-buffer order, shading, outlines, labels
(inside the picture, never overlapping), lines, determinism; the loop / exploded compositions."""

from __future__ import annotations

import io

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import annotate, guide_pictures, raster, render
from paraloop_core.fabrication.render import Arrow3, Item, Label, Line3, View

RED, BLUE = (220, 30, 30), (30, 60, 220)
TOP = View(size=(200, 160), direction=(0.0, 0.0, 1.0), up=(0.0, 1.0, 0.0), margin=0.25)


def box(center=(0.0, 0.0, 0.0), size=1.0) -> trimesh.Trimesh:
    m = trimesh.creation.box((size, size, size))
    m.apply_translation(center)
    return m


def pixels(items, labels=(), lines=(), view=TOP) -> np.ndarray:
    return np.asarray(render.render_image(items, labels, lines, view)).astype(int)


def test_red_cube_renders_red_inside_and_background_outside():
    img = pixels([Item(box(), RED)])
    h, w, _ = img.shape
    centre = img[h // 2, w // 2]
    assert centre[0] > 100 and centre[0] > 3 * centre[1] and centre[0] > 3 * centre[2]
    assert (img[2, 2] == 255).all() and (img[-3, -3] == 255).all()
    # the fitted cube spans the middle half of the picture's height (margin 0.25)
    red = (img[..., 0] > 3 * img[..., 1] + 30).any(1)
    rows = np.flatnonzero(red)
    assert abs(rows[0] - 0.25 * h) <= 3 and abs(rows[-1] - 0.75 * h) <= 3


def test_front_face_hides_back_face_with_the_front_shade():
    """Looking down z at a cube, the centre shows the top face (normal towards the eye):
    ambient + key light on the normal + full fill, not the bottom face (ambient only)."""
    img = pixels([Item(box(), RED, edges=False)])
    key = np.array(render.KEY_LIGHT)  # camera frame (right, up, towards the eye)
    shade = render.AMBIENT + render.KEY * key[2] / np.linalg.norm(key) + render.FILL
    centre = img[img.shape[0] // 2, img.shape[1] // 2]
    np.testing.assert_allclose(centre, np.round(np.array(RED) * shade), atol=1)


def test_nearer_mesh_wins_whatever_the_order():
    near, far = box((0.3, 0.0, 1.0)), box((-0.3, 0.0, -2.0))
    for items in ([Item(near, RED), Item(far, BLUE)], [Item(far, BLUE), Item(near, RED)]):
        img = pixels(items)
        h, w, _ = img.shape
        c = img[h // 2, w // 2]  # both cubes cover the centre; the red one is nearer
        assert c[0] > c[2]
        left = img[h // 2, int(0.3 * w)]  # only the blue one reaches there
        assert left[2] > left[0]


def test_output_is_deterministic():
    items = [Item(box(), RED), Item(box((1.5, 0, 0)), BLUE, alpha=0.5)]
    labels = [Label("red", (0, 0, 0.5), RED, item=0), Label("blue", (1.5, 0, 0.5), BLUE)]
    lines = [Line3((-2, 0, 0), (3, 0, 0), dashed=True), Arrow3((3, 1, 0), (2, 0, 0))]
    view = View(size=(300, 220))
    assert render.render(items, labels, lines, view) == render.render(items, labels, lines, view)


def test_png_has_the_view_size():
    png = render.render([Item(box(), RED)], view=View(size=(321, 123)))
    assert Image.open(io.BytesIO(png)).size == (321, 123)


def cross2(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def brute_cover(tri: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Pixel centres strictly inside ``tri`` (2D) and those within 1e-6 of an edge."""
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    p = np.stack([xx.ravel(), yy.ravel()], -1)
    d = []
    for k in range(3):
        a, b = tri[k], tri[(k + 1) % 3]
        e = b - a
        d.append((e[0] * (p[:, 1] - a[1]) - e[1] * (p[:, 0] - a[0])) / np.linalg.norm(e))
    d = np.stack(d, -1) * np.sign(cross2(tri[1] - tri[0], tri[2] - tri[0]))
    return (d > 1e-6).all(1), (np.abs(d) <= 1e-6).any(1)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-5, 45), min_size=6, max_size=6))
def test_rasterize_covers_the_pixel_centres_inside(coords):
    tri = np.array(coords).reshape(3, 2)
    if abs(cross2(tri[1] - tri[0], tri[2] - tri[0])) < 1.0:
        return  # near-degenerate: nothing to compare
    keys = raster.rasterize(tri[None], np.full((1, 3), 0.5), (40, 40))
    inside, edge = brute_cover(tri, (40, 40))
    covered = keys != raster.EMPTY
    assert np.array_equal(covered[~edge], inside[~edge])


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_zbuffer_keeps_the_nearest_triangle(seed):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 30, (5, 3, 2))
    depth = rng.uniform(0.05, 0.95, (5, 3))
    keys = raster.rasterize(xy, depth, (30, 30))
    yy, xx = np.mgrid[0:30, 0:30] + 0.5
    best, any_ = np.full(900, np.inf), np.full(900, np.inf)
    for f in range(5):
        inside, edge = brute_cover(xy[f], (30, 30))
        if abs(cross2(xy[f, 1] - xy[f, 0], xy[f, 2] - xy[f, 0])) < 1e-9:
            continue
        # depth of face f's plane at the pixel centres
        m = np.column_stack([xy[f], np.ones(3)])
        z = np.column_stack([xx.ravel(), yy.ravel(), np.ones(900)]) @ np.linalg.solve(m, depth[f])
        any_ = np.minimum(any_, np.where(inside | edge, z, np.inf))
        best = np.minimum(best, np.where(inside & ~edge, z, np.inf))
    got = (keys >> raster.FACE_BITS) / float((1 << raster.DEPTH_BITS) - 1)
    clear = np.isfinite(best)
    # where a face clearly covers the pixel, the buffer holds the nearest face there (a face
    # through the centre's edge may count or not)
    assert np.all(got[clear] <= best[clear] + 1e-6)
    assert np.all(got[clear] >= any_[clear] - 1e-6)


def test_cube_outline_has_six_silhouette_and_three_crease_edges():
    m = box()
    n = m.face_normals
    front = n @ np.array([1.0, 2.0, 3.0]) > 0
    edges = raster.feature_edges(np.asarray(m.faces), n, front, np.cos(np.radians(40)))
    assert len(edges) == 9


def test_outlines_are_drawn_dark():
    plain = pixels([Item(box(), RED, edges=False)], view=View(size=(200, 160)))
    lined = pixels([Item(box(), RED)], view=View(size=(200, 160)))
    assert (lined.sum(-1) < plain.sum(-1) - 60).sum() > 100


def test_translucent_item_blends_over_opaque():
    img = pixels([Item(box((0, 0, -2)), RED, edges=False),
                  Item(box((0, 0, 0)), BLUE, alpha=0.5, edges=False)])
    c = img[img.shape[0] // 2, img.shape[1] // 2]
    assert c[0] > 60 and c[2] > 60  # both show


def test_hidden_stretch_of_a_line_is_faint():
    line = Line3((-1.0, 0.0, -1.0), (1.0, 0.0, -1.0), (0, 0, 0), width=3.0)
    frame = np.array([[-1.0, -1.0, 0.0], [1.0, 1.0, 0.0]])
    view = View(size=(200, 160), direction=(0.0, 0.0, 1.0), up=(0.0, 1.0, 0.0), fit=frame)
    img = pixels([Item(box(), RED, edges=False)], lines=[line], view=view)
    cam = render.camera(view, frame, 1)
    row = int(cam.project(np.array([0.0, 0.0, -1.0]))[1])
    mid = img[row, img.shape[1] // 2]
    x_out = int(cam.project(np.array([-0.75, 0.0, -1.0]))[0])
    assert img[row, x_out].sum() < 100  # in the open: solid black
    assert mid[0] > 100  # behind the cube: mostly the cube's red


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 14))
def test_labels_stay_inside_and_never_overlap(seed, n):
    rng = np.random.default_rng(seed)
    size = (800, 600)
    anchors = rng.uniform([-50, -50], [850, 650], (n, 2))
    sizes = rng.uniform([30, 18], [180, 30], (n, 2))
    occ = np.zeros((600, 800), bool)
    occ[200:400, 250:550] = rng.random() < 0.7
    boxes = annotate.place_labels(anchors, sizes, size, occ, gap=6.0, border=4.0)
    assert boxes.shape == (n, 4)
    np.testing.assert_allclose(boxes[:, 2:] - boxes[:, :2], sizes)
    assert np.all(boxes[:, :2] >= 4.0 - 1e-9) and np.all(boxes[:, 2] <= 796.0 + 1e-9)
    assert np.all(boxes[:, 3] <= 596.0 + 1e-9)
    for i in range(n):
        for j in range(i):
            a, b = boxes[i], boxes[j]
            apart = (a[0] >= b[2] + 6 - 1e-9) or (b[0] >= a[2] + 6 - 1e-9) or \
                (a[1] >= b[3] + 6 - 1e-9) or (b[1] >= a[3] + 6 - 1e-9)
            assert apart, (i, j, a, b)


def test_labels_prefer_empty_space_near_the_anchor():
    occ = np.zeros((300, 400), bool)
    occ[100:200, 100:300] = True  # content around the anchor
    box_ = annotate.place_labels(np.array([[200.0, 150.0]]), np.array([[60.0, 20.0]]),
                                 (400, 300), occ)[0]
    assert not occ[int(box_[1]):int(box_[3]), int(box_[0]):int(box_[2])].any()
    assert np.linalg.norm(annotate.attach(np.array([200.0, 150.0]), box_) - [200, 150]) < 120


def test_too_many_labels_are_refused():
    with pytest.raises(FabricationError) as err:
        annotate.place_labels(np.full((30, 2), 50.0), np.full((30, 2), 40.0), (100, 100))
    assert err.value.reason == "bad-parameters"


def test_label_text_is_at_least_14_px_and_drawn():
    f = annotate.font(View().font_px)
    w, h = annotate.box_size("link 0", f)
    assert h >= 14 + 2 and w > 14
    bare = pixels([Item(box(), RED)], view=View(size=(300, 240)))
    labelled = pixels([Item(box(), RED)], [Label("link 0", (0, 0, 0.5), RED, item=0)],
                      view=View(size=(300, 240)))
    assert ((labelled < 60).all(-1) & ~(bare < 60).all(-1)).sum() > 20  # dark text pixels


def test_snap_moves_a_hidden_anchor_onto_its_item():
    who = np.full((50, 50), -1)
    who[10:40, 10:20] = 0
    who[10:40, 20:40] = 1  # item 1 hides item 0 right of column 20
    p = annotate.snap(np.array([30.5, 25.5]), who, 0, 2)
    assert who[int(p[1]), int(p[0])] == 0 and p[0] < 20
    assert np.array_equal(annotate.snap(np.array([30.5, 25.5]), who, None, 2), [30.5, 25.5])
    assert np.array_equal(annotate.snap(np.array([3.0, 4.0]), who, 5, 2), [3.0, 4.0])


def test_coverage_names_the_item_seen():
    who, _ = render.Coverage([Item(box((0, 0, 0)), RED), Item(box((3, 0, 0)), BLUE)]).seen(
        View(size=(120, 60), direction=(0, 0, 1), up=(0, 1, 0)))
    assert who.shape == (60, 120)
    assert set(np.unique(who)) == {-1, 0, 1}
    assert who[30, 20] == 0 and who[30, 100] == 1


@pytest.mark.parametrize("make", [
    lambda: Item(box(), (300, 0, 0)),
    lambda: Item("mesh", RED),
    lambda: Item(box(), RED, alpha=0.0),
    lambda: Label("", (0, 0, 0)),
    lambda: Label("x", (0, np.nan, 0)),
    lambda: View(size=(5, 5)),
    lambda: render.render([Item(box(), RED)], [Label("x", (0, 0, 0), item=3)]),
    lambda: render.render([Item(box(), RED)], view=View(direction=(0, 0, 0))),
])
def test_bad_input_is_refused(make):
    with pytest.raises(FabricationError) as err:
        make()
    assert err.value.reason == "bad-parameters"


def rod(p0, p1, r=0.2) -> trimesh.Trimesh:
    return trimesh.creation.cylinder(r, segment=np.array([p0, p1], float), sections=24)


def test_loop_scene_names_every_piece_and_joint():
    pts = np.array([[0, 0, 0], [4, 0, 0], [4, 3, 1], [0, 3, 0]], float)
    pieces = [guide_pictures.Piece(f"link {k}", rod(pts[k], pts[(k + 1) % 4]), c)
              for k, c in enumerate([RED, BLUE, (0, 160, 0), (200, 120, 0)])]
    joints = [guide_pictures.Joint(k, pts[(k + 1) % 4], np.array([0, 0, 1.0]), -0.3, 0.3, 0.3,
                                   piece=k) for k in range(4)]
    scene = guide_pictures.loop_scene(pieces, joints, size=(500, 380))
    texts = [lab.text for lab in scene.labels]
    assert texts == [f"link {k}" for k in range(4)] + [f"joint {k}" for k in range(4)]
    assert Image.open(io.BytesIO(scene.png())).size == (500, 380)
    where = guide_pictures.locator_scene(pieces, joints[1], (1, 2), scene.view)
    assert [it.alpha == 1.0 for it in where.items] == [False, True, True, False]
    assert [lab.text for lab in where.labels] == ["link 1", "link 2", "joint 1"]
    assert where.view == scene.view


def test_a_label_keeps_off_an_arrow():
    """A label goes where it hides no arrow when there is room elsewhere (without the arrow
    it takes that place: left of its anchor)."""
    anchor, size = np.array([[200.0, 150.0]]), np.array([[80.0, 20.0]])
    free = annotate.place_labels(anchor, size, (400, 300))[0]
    arrow = np.array([[[free[0] - 10, 152.0], [free[2] + 10, 152.0]]])  # through that place
    box = annotate.place_labels(anchor, size, (400, 300), arrows=arrow)[0]
    along = np.linspace(arrow[0, 0], arrow[0, 1], 50)
    assert not np.any((along[:, 0] > box[0]) & (along[:, 0] < box[2]) &
                      (along[:, 1] > box[1]) & (along[:, 1] < box[3]))


def test_an_upright_exploded_scene_draws_the_axis_top_to_bottom():
    """The base's picture: the rod's axis vertical, +axis (towards the plate) downwards."""
    w = np.array([0.0, 0.0, -1.0])
    joint = guide_pictures.Joint(0, np.zeros(3), w, -2.0, 1.0, 0.2)
    rod_piece = guide_pictures.Piece("rod", rod((0, 0, 0), (0, 0, -1), 0.05), BLUE, focus=True)
    scene = guide_pictures.exploded_scene([([rod_piece], -1.0)], joint, upright=True)
    cam = render.camera(scene.view, np.array([[0.0, 0, 0], [0, 0, -1]]), 1)
    top, below = cam.project(np.zeros(3)), cam.project(w)
    assert abs(below[0] - top[0]) < 1e-6 * abs(below[1] - top[1]) and below[1] > top[1]
    arrow = next(ln for ln in scene.lines if isinstance(ln, Arrow3))
    assert (np.array(arrow.head) - arrow.tail) @ w > 0  # the rod goes down into its place


def test_exploded_scene_pulls_groups_apart_along_the_axis():
    w = np.array([1.0, 0.0, 0.0])
    joint = guide_pictures.Joint(2, np.zeros(3), w, -0.5, 1.0, 0.4)
    pin = guide_pictures.Piece("pin", rod((0, 0, 0), (1, 0, 0), 0.1), (250, 200, 0), focus=True)
    boss = guide_pictures.Piece("bore", rod((0.2, 0, 0), (1, 0, 0), 0.4), BLUE, focus=True)
    scene = guide_pictures.exploded_scene([([pin], 0.0), ([boss], 3.0)], joint, size=(400, 300))
    shift = scene.items[1].mesh.bounds[0] - boss.mesh.bounds[0]
    np.testing.assert_allclose(shift, 3.0 * w, atol=1e-9)
    arrows = [ln for ln in scene.lines if isinstance(ln, Arrow3)]
    axes = [ln for ln in scene.lines if isinstance(ln, Line3)]
    assert len(arrows) == 1 and len(axes) == 1 and axes[0].dashed
    # the arrow points back along -w, towards the joint
    assert (np.array(arrows[0].head) - arrows[0].tail) @ w < 0
    # the axis is drawn left to right: +w to the right of the picture
    cam = render.camera(scene.view, np.array([[0.0, 0, 0], [1, 0, 0]]), 1)
    assert cam.project(w)[0] > cam.project(np.zeros(3))[0]
    assert {lab.text for lab in scene.labels} == {"pin", "bore", "axis of joint 2"}
    assert Image.open(io.BytesIO(scene.png())).size == (400, 300)
    # groups pulled both ways: one arrow per direction (the farthest group's), on opposite
    # sides of the axis, each pointing back towards the joint
    nut = guide_pictures.Piece("nut", rod((1.0, 0, 0), (1.2, 0, 0), 0.2), BLUE)
    both = guide_pictures.exploded_scene([([pin], -2.0), ([boss], 3.0), ([nut], 1.5)], joint,
                                         size=(400, 300))
    arrows = [ln for ln in both.lines if isinstance(ln, Arrow3)]
    along = [float((np.array(a.head) - a.tail) @ w) for a in arrows]
    assert len(arrows) == 2 and sorted(np.sign(along)) == [-1.0, 1.0]
    assert max(abs(x) for x in along) == pytest.approx(0.75 * 3.0)  # the farthest group's
    across = [np.array(a.tail) - (np.array(a.tail) @ w) * w for a in arrows]
    assert float(across[0] @ across[1]) < 0  # opposite sides of the axis


@pytest.mark.slow
def test_assembly_pictures_of_the_printed_loop():
    import fab_fixtures as F

    asm = F.printed().assembly
    scenes = dict(guide_pictures.assembly_scenes(asm))
    assert list(scenes) == ["guide_loop.png"] + [f"guide_joint_{j}.png" for j in range(6)] \
        + ["guide_base.png"]
    loop = scenes["guide_loop.png"]
    assert [lab.text for lab in loop.labels] == [f"link {k}" for k in range(6)] + [
        "base plate", "rod"] + [f"joint {k}" for k in range(6)]
    for jt in asm.joints:
        j = jt.index
        texts = {lab.text for lab in scenes[f"guide_joint_{j}.png"].labels}
        assert {f"link {j}", f"link {(j + 1) % 6}", f"axis of joint {j}"} <= texts
        assert ({"screw", "washer", "lock nut (into its trap)"} if jt.kind == "m3" else
                {"rod", f"rod cap {j}"}) <= texts
    png = scenes["guide_joint_0.png"].png()
    img = np.asarray(Image.open(io.BytesIO(png))).reshape(-1, 3).astype(int)
    pin = np.abs(img - guide_pictures.PIN_COLOR).sum(1) < 150  # the screw shows in its colour
    assert pin.sum() > 200
