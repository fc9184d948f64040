"""The independent checker of a printed export (``tests/independent/printed_check.py``, issue 26).

Known answers for its measuring tools, the five examples' plain exports checked against the
issue's "Done when", and a good export damaged four ways (a thinner bar, a shrunk base plate,
a part tilted on the bed, a bore filled in), each of which must be reported as its failure.
The damage starts from ``tests/data/printed_sun-path-fit`` (an export of the printed loop:
result.json, report.json, STL and 3MF files; regenerate it with ``paraloop export
assets/designs/sun-path-fit.json --out DIR`` when the export's format changes).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import manifold3d as m3
import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from independent import joint_profile as jp
from independent import meshgeom as mg
from independent import printed_check as pc
from independent import printed_layout, printed_stand
from independent.printed_kin import load_export

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = Path(__file__).parent / "data" / "printed_sun-path-fit"
EXAMPLES = ["tv8", "sun-disc", "shading-panel", "sun-path-fit", "arc-sculpture"]


# --- the measuring tools on shapes of known size --------------------------------------------

@settings(max_examples=40, deadline=None)
@given(st.floats(1.0, 30.0), st.floats(0.0, 6.3), st.floats(-50, 50), st.floats(-50, 50))
def test_least_width_of_a_hexagon_is_its_flats(r, turn, x, y):
    """A regular hexagon of corner radius r is r sqrt(3) wide however it is placed."""
    a = turn + np.arange(6) * np.pi / 3
    pts = np.stack([x + r * np.cos(a), y + r * np.sin(a)], axis=1)
    assert mg.least_width(pts) == pytest.approx(r * np.sqrt(3), rel=1e-9)


def test_area_above_a_level_of_a_sloped_triangle():
    """Right triangle rising from 0 to 2 along x: above z = 1 lies a quarter of it."""
    z = np.array([[0.0, 2.0, 0.0]])  # heights of corners (0,0), (2,0), (0,2): z = x
    area = np.array([2.0])
    assert mg.area_above(z, area, 1.0)[0] == pytest.approx(0.25 * 2.0)
    assert mg.area_above(z, area, -1.0)[0] == pytest.approx(2.0)
    assert mg.area_above(z, area, 3.0)[0] == 0.0


def test_sections_of_a_box_measure_its_least_side():
    box = trimesh.creation.box(extents=[40.0, 8.0, 12.0])
    sec = mg.Sections(box.vertices, box.faces, np.array([-20.0, 0, 0]), np.array([1.0, 0, 0]),
                      np.array([5.0, 20.0, 35.0]))
    for k in range(3):
        width, loops = mg.section_width(sec, k, np.zeros(2))
        assert loops == 1 and width == pytest.approx(8.0)
    assert mg.section_width(sec, 1, np.array([9.0, 0.0]))[0] == 0.0  # outside the material


def _tube(r_in: float, r_out: float, length: float, sections: int = 64) -> trimesh.Trimesh:
    outer = trimesh.creation.cylinder(radius=r_out, height=length, sections=sections)
    inner = trimesh.creation.cylinder(radius=r_in, height=length + 2, sections=sections)
    return outer.difference(inner, engine="manifold")


def test_profile_of_a_tube():
    """A 3.4/8 mm tube, 12 mm long, holds a 6 mm axle over 12 mm with a 4.6 mm wall (the
    station count gives a lower bound one step short at most)."""
    p = jp.profile(_tube(3.4, 8.0, 12.0), np.zeros(3), np.array([0, 0, 1.0]), -8.0, 8.0)
    held = jp.held(p, 3.0)
    assert 12.0 - 2 * jp.STEP_MM <= jp.run_length(held) <= 12.0
    wall = jp.thinnest_wall(p, jp.surrounded(p))[0]
    assert wall == pytest.approx(8.0 - 3.4, abs=0.02)
    assert jp.run_length(jp.held(p, 1.5)) == 0.0  # a 3 mm screw rattles in it
    assert jp.floor(p, np.ones(len(p.s), bool)) is None  # a through bore


def test_floor_of_a_blind_bore():
    """A 3.4 mm bore 8 mm deep into a 12 mm boss leaves a 4 mm floor."""
    boss = trimesh.creation.cylinder(radius=8.0, height=12.0, sections=64)
    bore = trimesh.creation.cylinder(radius=3.4, sections=64, segment=[[0, 0, -7.0], [0, 0, 2.0]])
    p = jp.profile(boss.difference(bore, engine="manifold"), np.zeros(3),
                   np.array([0, 0, 1.0]), -8.0, 8.0)
    assert 4.0 - 2 * jp.STEP_MM <= jp.floor(p, np.abs(p.s) <= 6.0) <= 4.0


@pytest.mark.parametrize("floor", [None, 2.0])
def test_a_capless_rod_is_retained_only_by_a_blind_floor(floor):
    """A grounding rod without its cap ends 8 mm into the turning link's 12 mm boss: with a
    floor 2 mm thick 0.3 mm past its tip the link cannot slide off (retained); with the
    bore drilled through, the checker says the link can slide off the rod."""
    from independent import printed_joints as pj

    boss = trimesh.creation.cylinder(radius=8.0, height=12.0, sections=64)  # s in [-6, 6]
    top = 6.0 if floor is None else 6.0 - floor
    bore = trimesh.creation.cylinder(radius=2.2, sections=64, segment=[[0, 0, -7.0], [0, 0, top]])
    p = jp.profile(boss.difference(bore, engine="manifold"), np.zeros(3),
                   np.array([0, 0, 1.0]), -9.0, 9.0)
    jt = {"joint": 0, "kind": "rod",
          "pieces": [{"role": "rod", "s_mm": [-20.0, top - 0.3], "radius_mm": 2.0,
                      "printed": False}]}

    class Ex:
        grounded = 0  # link 0 holds the rod; link 1 turns on it

    out = {"links": [{"link": 0}, {"link": 1}]}
    fails = pj._blind_retention(Ex(), jt, [None, p], out, 1.2)
    if floor is None:
        assert fails and "slide off" in fails[0]
    else:
        assert not fails
        assert floor - 2 * jp.STEP_MM <= out["retention"]["blind_floor_mm"] <= floor
        assert out["retention"]["floor_past_tip_mm"] <= 0.3 + jp.STEP_MM


def test_hex_trap_takes_a_nut_and_stops_it_turning():
    """A 5.8 mm hexagonal pocket takes a 5.5 mm nut with 0.15 mm to spare and blocks it."""
    block = trimesh.creation.box(extents=[20.0, 20.0, 10.0])
    pocket = trimesh.creation.cylinder(radius=2.9 / np.cos(np.pi / 6), height=12.0, sections=6)
    p = jp.profile(block.difference(pocket, engine="manifold"), np.zeros(3),
                   np.array([0, 0, 1.0]), -5.0, 5.0)
    clear, blocked = jp.hex_fit(p, -4.0, 4.0, 5.5)
    assert clear == pytest.approx(0.15, abs=0.01) and blocked == 1.0
    assert jp.hex_fit(p, -4.0, 4.0, 6.0)[0] < 0  # a 6 mm nut does not go in


# --- the five examples, exported as a maker would -------------------------------------------

@pytest.mark.parametrize("name", [pytest.param(
    n, marks=() if n == "tv8" else (pytest.mark.slow,)) for n in EXAMPLES])
def test_plain_export_passes_the_independent_checks(name, tmp_path):
    out = tmp_path / name
    run = subprocess.run([sys.executable, "-m", "app.cli.main", "export",
                          f"assets/designs/{name}.json", "--out", str(out), "--quiet"],
                         cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert run.returncode == 0 and (out / "result.json").exists(), run.stderr[-400:]
    found = pc.check_export(out)
    # what the independent checker finds is what the export says: only links the report
    # names as not lying flat (print_flat_slack_mm under flat.FLAT_SLACK, down to which every
    # bore keeps its wall; no keel; a warning) may need supports
    from paraloop_core.fabrication.flat import lies_flat

    report = json.loads((out / "report.json").read_text())
    in_pieces = {p["link"] for p in report["parts"] if "printed_as" in p}
    lifted = [i for i, s in enumerate(report["print_flat_slack_mm"])
              if not lies_flat(s) and not report["keels_mm"][i] and i not in in_pieces]
    unannounced = [f for f in found["failures"]
                   if not (f.startswith("print: link_") and int(f.split()[1][5:]) in lifted)]
    assert not unannounced, "\n".join(unannounced + [json.dumps(pc.summary(found))])
    assert not lifted or any("cannot lie on the bar's face" in w and
                             all(str(i) in w for i in lifted) for w in report["warnings"])
    if name == "tv8":  # every link of tv8 lies on its bar's face (its rod link included)
        assert not lifted and not found["failures"]


@pytest.mark.parametrize("seed", [62037, 62083])
def test_random_designs_export_whole_bars_and_a_base_that_stands(seed, tmp_path):
    """Two random generic designs (``independent.generic_designs``) that once printed badly:
    62037's first grounding rod put its cap's room across link 3's bar (a crescent where the
    bar should be; now another rod is taken, the same realization kept); 62083 turns a joint
    half a turn within a sliver of its cycle, and the base's motion bound over uniform
    samples refused every rod (now :func:`loops.cycle_samples`: it stands). Exported as the
    benchmark does, both pass the independent checker, stand, and cut no bar."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import printability

    row = printability.run_one((f"random-{seed}", (seed,)), tmp_path)
    assert row["outcome"] == "ok" and row["failures"] == [], row
    report = json.loads((tmp_path / f"random-{seed}" / "report.json").read_text())
    assert report["base"]["stands"] and report["mount"] is None
    assert not any(any(j["bar_cut"]) for j in report["joints"])


def test_a_design_refused_for_room_names_a_bed_on_which_it_prints(tmp_path):
    """Random 62219: at the generic bed no realization tried leaves its joints room (the
    export refuses, exit 2); the refusal names the smallest larger bed on which one has room
    (:mod:`remedy`), and on that bed the export is whole: the independent checker finds only
    slender bars, which the report names with the pair that limits them."""
    from independent.generic_designs import random_design

    design = tmp_path / "random-62219.json"
    design.write_text(json.dumps(random_design(62219)))

    def export(*extra: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "app.cli.main", "export", str(design),
                               "--out", str(tmp_path / "out"), "--quiet", *extra],
                              cwd=ROOT, capture_output=True, text=True, timeout=900)

    refused = export()
    assert refused.returncode == 2 and not (tmp_path / "out").exists(), refused.stderr[-400:]
    bed = re.search(r"--bed (\d+),(\d+),(\d+)\), where", refused.stderr)
    assert bed is not None, refused.stderr[-600:]
    assert int(bed[1]) > 250  # larger than the generic bed
    run = export("--bed", ",".join(bed.groups()))
    assert run.returncode == 0, run.stderr[-400:]
    found = pc.check_export(tmp_path / "out")
    assert all(f.startswith("bar: ") for f in found["failures"]), found["failures"]
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert not found["failures"] or report["sizing"]["limiting_pair"]


def test_slender_bars_name_a_bed_that_brings_them_within_the_floors(tmp_path):
    """Random 62233 prints on the generic bed with bars thinner than the floors (the
    certificate's room at the size the bed allows); the warning and ``sizing.larger_print``
    name the smallest larger bed on which a realization has bars within them
    (:func:`remedy.stronger_print`), and the export on that bed has them: the independent
    checker finds no failure, the bars as wide as the report predicted."""
    from independent.generic_designs import random_design

    design = tmp_path / "random-62233.json"
    design.write_text(json.dumps(random_design(62233)))

    def export(out: str, *extra: str) -> dict:
        run = subprocess.run([sys.executable, "-m", "app.cli.main", "export", str(design),
                              "--out", str(tmp_path / out), "--quiet", *extra],
                             cwd=ROOT, capture_output=True, text=True, timeout=900)
        assert run.returncode == 0, run.stderr[-400:]
        return json.loads((tmp_path / out / "report.json").read_text())

    slender = export("here")
    larger = slender["sizing"]["larger_print"]
    assert larger["bed_mm"][0] > 250 and larger["length_per_width"] <= 28.0 + 1e-9
    bed = ",".join(f"{v:.0f}" for v in larger["bed_mm"])
    assert any(f"--bed {bed}" in w for w in slender["warnings"]), slender["warnings"]
    export("there", "--bed", bed)
    found = pc.check_export(tmp_path / "there")
    assert not found["failures"], found["failures"]
    assert pc.summary(found)["min_bar_width_mm"] >= 0.95 * larger["bar_width_mm"]


# --- a good export damaged: each damage is reported --------------------------------------------

@pytest.fixture
def sample(tmp_path) -> Path:
    folder = tmp_path / "export"
    shutil.copytree(SAMPLE, folder)
    return folder


def _write(mesh: trimesh.Trimesh, path: Path) -> None:
    path.write_bytes(trimesh.exchange.stl.export_stl(mesh))


def test_sample_is_a_good_export(sample):
    found = pc.check_export(sample, collisions=False)
    assert not found["failures"], "\n".join(found["failures"])


def test_thinner_bar_is_reported(sample):
    ex = load_export(sample)
    link, a, b = pc.bars(ex)[2]
    axis = (b - a) / np.linalg.norm(b - a)
    width = pc.check_bars(ex)[0][2]["min_width_mm"]
    shrink = 0.8 * pc.MIN_WIDTH_MM / width  # the bar ends 80 % of the least width
    mesh = ex.links[link].copy()
    along = (mesh.vertices - a) @ axis
    across = mesh.vertices - a - along[:, None] * axis
    mesh.vertices = a + along[:, None] * axis + shrink * across
    _write(mesh, sample / f"link_{link}.stl")
    rows, fails = pc.check_bars(load_export(sample))
    assert rows[2]["min_width_mm"] == pytest.approx(shrink * width, rel=1e-3)
    assert any(f.startswith(f"bar: link {link} is ") for f in fails)


def test_shrunk_base_plate_is_reported(sample):
    ex = load_export(sample)
    w = ex.world_from_home()
    plate = ex.mesh("base_plate")
    rod = pc.check_stand(ex)[0]["rod"]
    centre = (w[:3, :3] @ np.asarray(rod["bottom"]) + w[:3, 3])[:2]
    world = plate.vertices @ w[:3, :3].T + w[:3, 3]
    world[:, :2] = centre + 0.25 * (world[:, :2] - centre)  # a quarter of the plate's size
    plate.vertices = (world - w[:3, 3]) @ w[:3, :3]
    _write(plate, sample / "base_plate.stl")
    figures, fails = pc.check_stand(load_export(sample))
    assert figures["com_margin_share"] < printed_stand.MARGIN_SHARE
    assert any(f.startswith("stand: the centre of mass comes") for f in fails)


def test_part_tilted_on_the_bed_is_reported(sample):
    path = next(p for p in printed_layout.plate_files(sample)
                if any(n.startswith("link_") for n in trimesh.load(p).geometry))
    scene = trimesh.load(path)
    name = next(n for n in scene.geometry if n.startswith("link_"))
    mesh = scene.geometry[name]
    mesh.apply_transform(trimesh.transformations.rotation_matrix(np.radians(35), [1, 0, 0],
                                                                mesh.centroid))
    mesh.apply_translation([0, 0, -mesh.bounds[0, 2]])
    path.write_bytes(scene.export(file_type="3mf"))
    figures, fails = pc.check_layout(load_export(sample))
    row = next(r for r in figures["parts"] if r["name"] == name)
    assert row["support_share"] > printed_layout.MAX_SUPPORT_SHARE
    assert any(f.startswith(f"print: {name} needs support") for f in fails)


def test_filled_bore_is_reported(sample):
    ex = load_export(sample)
    jt = ex.report["joints"][0]
    lo, hi = jt["bosses_mm"][1]
    o, a = np.asarray(jt["origin_mm"]), np.asarray(jt["axis"])
    plug = trimesh.creation.cylinder(radius=jt["axle_diameter_mm"], sections=32,
                                     segment=[o + a * (lo - 1), o + a * (hi + 1)])
    link = ex.links[1]
    solid = m3.Manifold(m3.Mesh(vert_properties=np.asarray(link.vertices, np.float32),
                                tri_verts=np.asarray(link.faces, np.uint32)))
    plugged = solid + m3.Manifold(m3.Mesh(vert_properties=np.asarray(plug.vertices, np.float32),
                                          tri_verts=np.asarray(plug.faces, np.uint32)))
    out = plugged.to_mesh()
    _write(trimesh.Trimesh(out.vert_properties[:, :3], out.tri_verts), sample / "link_1.stl")
    figures, fails, _ = pc.check_joint(load_export(sample), 0, ex.report["sizing"]["wall_mm"])
    assert figures["links"][1]["engagement_mm"] == 0.0
    assert any(f.startswith("joint 0: link 1 material inside the screw") for f in fails)
    assert any(f.startswith("joint 0: link 1 holds the") for f in fails)
    assert not any(f.startswith("joint 0: link 0") for f in fails)  # the other link is whole


def test_result_of_another_loop_is_reported(sample):
    """result.json naming a loop other than the printed one: its axes are metres off the
    parts' joints, far beyond the micrometre the checker allows (a wrong loop, not round-off)."""
    result = json.loads((sample / "result.json").read_text())
    real = result["realization"]
    real["loop"] = (real.get("loop", result["loop"]) + 1) % len(result["loops"])
    (sample / "result.json").write_text(json.dumps(result))
    found = pc.check_export(sample, collisions=False)
    assert found["figures"]["closure_mm"] > 1000 * pc.CLOSURE_TOL_MM
    assert any(f.startswith("result.json: the loop's joint axes part by") for f in
               found["failures"])
