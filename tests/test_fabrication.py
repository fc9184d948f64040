"""Export files, built-in verification, grounding and the ``paraloop export`` command."""

from __future__ import annotations

import argparse
import io
import itertools
import json

import numpy as np
import pytest
import trimesh
from test_parts import example_assembly, example_loop

from paraloop_core.algebra import dq, poly
from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import export, grounding, parts
from paraloop_core.linkage import loops


@pytest.fixture(scope="module")
def exported() -> export.ExportResult:
    jf, pts, radius = example_loop()
    return export.export_parts(jf, pts, radius, spec=parts.PartSpec(size_mm=150.0))


def test_export_files_and_watertight_parts(exported):
    files = dict(exported.files)
    assert set(files) == {f"link_{i}.stl" for i in range(6)} | {
        "paraloop.3mf", "assembly.glb", "report.json", "assembly.md"} | {
        f"assembly_step_{k}.png" for k in range(1, 8)}
    home = {}
    for i in range(6):
        mesh = trimesh.load(io.BytesIO(files[f"link_{i}.stl"]), file_type="stl")
        assert mesh.is_watertight and mesh.volume > 0
        home[f"link_{i}"] = mesh
    # the 3MF: the same parts laid flat on the default bed, side by side
    scene = trimesh.load(io.BytesIO(files["paraloop.3mf"]), file_type="3mf")
    assert sorted(scene.geometry) == [f"link_{i}" for i in range(6)]
    laid = {name: scene.geometry[name].copy().apply_transform(scene.graph[name][0])
            for name in scene.graph.nodes_geometry}
    bounds = np.array([m.bounds for m in laid.values()])
    assert np.allclose(bounds[:, 0, 2], 0.0, atol=1e-6)  # on the bed
    assert np.all(bounds[:, 0] >= -1e-6) and np.all(bounds[:, 1] <= export.DEFAULT_BED_MM)
    for name, mesh in laid.items():
        assert mesh.is_watertight and mesh.volume == pytest.approx(home[name].volume, rel=1e-6)
        touching = mesh.area_faces[(mesh.triangles_center[:, 2] < 0.05)
                                   & (mesh.face_normals[:, 2] < -0.999)].sum()
        entry = next(p for p in exported.report["print_layout"]["parts"] if p["name"] == name)
        assert touching == pytest.approx(entry["contact_mm2"], rel=1e-6) and touching > 0
    lo, hi = bounds[:, 0, :2], bounds[:, 1, :2]  # footprints do not overlap
    for a, b in itertools.combinations(range(6), 2):
        assert np.any(hi[a] <= lo[b] + 1e-6) or np.any(hi[b] <= lo[a] + 1e-6)
    guide = files["assembly.md"].decode()
    assert all(f"the pin of link_{i} goes into the bore of link_{(i + 1) % 6}" in guide
               for i in range(6))
    assert all(f"(assembly_step_{k}.png)" in guide for k in range(1, 8))
    assert files["assembly_step_1.png"][:8] == b"\x89PNG\r\n\x1a\n"
    glb = trimesh.load(io.BytesIO(files["assembly.glb"]), file_type="glb")
    assert len(glb.geometry) == 6


def test_report_verifies_the_example(exported):
    report = json.loads(dict(exported.files)["report.json"])
    ver = report["verification"]
    assert ver["ok"] and ver["watertight"] and ver["collisions"] == 0
    assert all(p["pieces"] == 1 for p in ver["parts"])
    assert ver["samples"] == 720 and len(ver["pairs"]) == 15
    assert 0 < ver["continuous_min_gap_mm"] <= ver["min_gap_mm"]
    clearance = report["spec"]["clearance_mm"]
    assert ver["joint_clearance_mm"] == pytest.approx(clearance, abs=0.02)
    assert report["grounding"]["certified_clearance_mm"] > 0
    assert report["scale_mm_per_unit"] > 0


def test_verification_finds_collisions():
    """Fat bars (far beyond the realized radius) must be reported as colliding."""
    jf, pts, radius = example_loop()
    asm = parts.build_assembly(jf, pts, radius, parts.PartSpec(rho_mm=25.0, boss_radius_mm=26.0))
    ver = export.verify_assembly(asm, samples=24)
    assert not ver["ok"]
    assert ver["collisions"] > 0 and ver["min_gap_mm"] == 0.0
    worst = max(ver["pairs"], key=lambda p: p["max_intersection_mm3"])
    assert worst["max_intersection_mm3"] > 0


def test_verification_refines_fast_cells():
    """Few samples: cells whose motion bound exceeds the gap are subdivided until certified."""
    ver = export.verify_assembly(example_assembly(False), samples=16)
    assert ver["ok"]
    assert ver["max_pair_samples"] > 16


def test_verification_without_a_speed_bound(monkeypatch):
    """Where a motion passes too close to a singular pose for a speed bound (random design 16,
    links 1 and 4), the joint-angle bound alone certifies the cycle; it is sound: at least the
    largest sampled displacement."""
    from paraloop_core.realization import motion_bound as mbm

    jf, pts, radius = example_loop()
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
    ver = export.verify_assembly(example_assembly(False), samples=64)
    assert ver["ok"] and ver["continuous_min_gap_mm"] > 0


def test_export_design_parts_and_progress():
    jf, pts, radius = example_loop()
    seen = []
    files = export.export_design_parts(jf, pts, radius, ground=False, samples=64,
                                            progress=lambda f, m: seen.append(f))
    assert [n for n, _ in files][-1] == "report.json"
    assert all(isinstance(b, bytes) and b for _, b in files)
    assert seen and seen[-1] == pytest.approx(1.0) and np.all(np.diff(seen) >= -1e-12)


def test_grounding_column():
    jf, pts, radius = example_loop()
    g = grounding.ground_column(jf, pts, bar_radius=radius, hub_radius=radius,
                                hub_extent=0.0)
    assert g.axis in (g.link, (g.link - 1) % 6)
    assert g.clearance > 0 and g.sampled_clearance >= g.clearance
    assert g.bottom[2] == pytest.approx(g.ground_z)
    for link in range(6):  # the default is the best of every link's best
        try:
            other = grounding.ground_column(jf, pts, bar_radius=radius, hub_radius=radius,
                                            hub_extent=0.0, link=link)
        except FabricationError:
            continue
        assert other.link == link and other.clearance <= g.clearance
    # dense check in the grounded link's frame: the column against the other links' bars
    u = np.linspace(0.0, 1.0, 1001)
    poses = dq.to_matrix(loops.link_poses(jf, poly.param_to_t(u)))
    rel = np.linalg.inv(poses[:, g.link, None]) @ poses  # (T, 6, 4, 4)
    col = g.top + np.linspace(g.radius / np.linalg.norm(g.bottom - g.top), 1.0, 200)[:, None] * (
        g.bottom - g.top)
    lam = np.linspace(0.0, 1.0, 100)[:, None]
    for j in range(6):
        if j == g.link:
            continue
        bar = pts[2 * j] + lam * (pts[2 * j + 1] - pts[2 * j])  # (100, 3)
        moved = np.einsum("tab,nb->tna", rel[:, j, :3, :3], bar) + rel[:, j, None, :3, 3]
        d = np.linalg.norm(moved[:, :, None] - col[None, None], axis=-1).min()
        spacing = max(np.linalg.norm(pts[2 * j + 1] - pts[2 * j]) / 99,
                      np.linalg.norm(g.bottom - g.top) / 199)
        assert d - g.radius - radius + spacing >= g.clearance
    with pytest.raises(FabricationError) as err:  # A_0 points straight down, so ground above
        grounding.ground_column(jf, pts, bar_radius=radius, hub_radius=radius, hub_extent=0.0,
                                link=0, axis=0, ground_z=float(pts[:, 2].max()) + 1)
    assert err.value.reason == "grounding"
    with pytest.raises(FabricationError):
        grounding.ground_column(jf, pts, bar_radius=-1.0, hub_radius=radius, hub_extent=0.0)


def test_cli_export(tmp_path):
    from app.cli import export as export_cmd

    parser = argparse.ArgumentParser()
    export_cmd.register(parser.add_subparsers())
    args = parser.parse_args(["export", "assets/designs/sun-disc.json", "--out", str(tmp_path),
                              "--size-mm", "500", "--no-ground", "--samples", "90", "--quiet",
                              "--3dm"])
    assert args.func(args) == 0
    assert (tmp_path / "paraloop.3mf").stat().st_size > 0
    assert json.loads((tmp_path / "report.json").read_text())["verification"]["ok"]
    assert "![step 7](assembly_step_7.png)" in (tmp_path / "assembly.md").read_text()
    # the Rhino file holds the STLs' geometry, one named part per layer, in mm
    import rhino3dm

    model = rhino3dm.File3dm.Read(str(tmp_path / "paraloop.3dm"))
    assert model.Settings.ModelUnitSystem == rhino3dm.UnitSystem.Millimeters
    assert sorted(layer.Name for layer in model.Layers) == [f"link_{i}" for i in range(6)]
    for obj in model.Objects:
        stl = trimesh.load(tmp_path / f"{obj.Attributes.Name}.stl")
        box = obj.Geometry.GetBoundingBox()
        assert len(obj.Geometry.Vertices) >= len(stl.vertices) > 0
        assert np.allclose([box.Min.X, box.Min.Y, box.Min.Z], stl.bounds[0], atol=1e-4)
        assert np.allclose([box.Max.X, box.Max.Y, box.Max.Z], stl.bounds[1], atol=1e-4)
    from app.cli.main import main

    assert main(["export", "assets/designs/sun-disc.json", "--out", str(tmp_path),
                 "--quiet"]) == 2  # refuses to overwrite, before any work
    with pytest.raises(SystemExit) as bad:  # refused by the argument parser: exit code 2
        parser.parse_args(["export", "assets/designs/sun-disc.json", "--out",
                           str(tmp_path / "x"), "--clearance", "-1", "--quiet"])
    assert bad.value.code == 2
    assert not (tmp_path / "x").exists()


def test_print_in_place_parts_verify():
    ver = export.verify_assembly(example_assembly(True), samples=90)
    assert ver["ok"] and ver["printable"]
    assert ver["joint_clearance_mm"] == pytest.approx(0.3, abs=0.02)


def test_carved_parts_export_and_verify():
    jf, pts, radius = example_loop()
    res = export.export_parts(jf, pts, radius, space_radius=3 * radius, resolution=56,
                                   samples=32, ground=False)
    ver = res.report["verification"]
    assert ver["ok"] and ver["watertight"]
    assert any(res.report["carving"]["meshed"])
    # carved bodies are bigger than bare bars
    bare = example_assembly(False)
    assert sum(p["volume_mm3"] for p in ver["parts"]) > sum(
        p.manifold.volume() for p in bare.parts)


def test_long_part_lies_diagonally_on_the_bed():
    """A 300 mm bar does not fit a 250 x 210 bed square-on: the layout turns it onto the
    diagonal (still flat, inside the bed), as sizing.fits_bed promised."""
    from paraloop_core.fabrication import guide, sizing

    bar = trimesh.creation.box([300.0, 12.0, 8.0])
    bar.apply_transform(trimesh.transformations.rotation_matrix(0.3, [0.2, 0.5, 1.0]))
    bed = (250.0, 210.0, 210.0)
    assert sizing.fits_bed(np.array([[300.0, 12.0, 8.0]]), sizing.Printer("t", bed))[0]
    (place,) = guide.bed_layout({"bar": bar}, bed)
    laid = bar.copy().apply_transform(place.transform)
    assert np.allclose(laid.bounds[0, 2], 0.0, atol=1e-6)
    assert laid.extents[2] == pytest.approx(8.0, abs=1e-3)
    assert np.all(laid.bounds[0] >= -1e-6) and np.all(laid.bounds[1] <= np.array(bed) + 1e-6)


def test_a_part_torn_by_its_tessellation_is_built_again(monkeypatch):
    """A boolean may pinch two vertices onto one point (random design 49): the part then is
    not watertight as a slicer reads it, and the parts are built again with more segments."""
    jf, pts, radius = example_loop()
    seen = []
    real_export = export.export_assembly

    def flaky(asm, **kw):
        seen.append(asm.spec.segments)
        if len(seen) == 1:
            raise FabricationError("link_2 is not watertight", "not-watertight")
        return real_export(asm, **kw)

    monkeypatch.setattr(export, "export_assembly", flaky)
    res = export.export_parts(jf, pts, radius, spec=parts.PartSpec(size_mm=150.0), verify=False)
    assert seen == [48, 50] and res.assembly.spec.segments == 50
    seen.clear()

    def torn(asm, **kw):
        seen.append(asm.spec.segments)
        raise FabricationError("link_2 is not watertight", "not-watertight")

    monkeypatch.setattr(export, "export_assembly", torn)
    with pytest.raises(FabricationError, match="not watertight"):
        export.export_parts(jf, pts, radius, spec=parts.PartSpec(size_mm=150.0), verify=False)
    assert seen == [48, 50, 54]  # every tessellation tried, then the error
