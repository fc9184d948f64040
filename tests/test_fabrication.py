"""``paraloop export``: a plain export of a bundled example writes the printed loop's files,
read back independently; refusals (one line, exit 2, nothing written)."""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from test_animate import animated, read_glb

from app.cli.main import main
from paraloop_core import pipeline

TV8 = Path(__file__).resolve().parents[1] / "assets" / "designs" / "tv8.json"


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> tuple[Path, int, str]:
    """``paraloop export tv8.json --out DIR --quiet --3dm`` (no other flag): the folder,
    exit code and standard output."""
    import contextlib

    out = tmp_path_factory.mktemp("export") / "parts"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["export", str(TV8), "--out", str(out), "--quiet", "--3dm"])
    return out, code, buf.getvalue()


def test_plain_export_writes_the_printed_loop(exported):
    out, code, stdout = exported
    assert code == 0
    report = json.loads((out / "report.json").read_text())
    plates = report["print_layout"]["plates"]
    b = report["base"]
    names = {p.name for p in out.iterdir()}
    parts = {p["name"] for p in report["parts"]}
    assert parts == {f"link_{i}" for i in range(6)} | {"base_plate", f"rod_cap_{b['rod_joint']}"}
    assert names == {f"{p}.stl" for p in parts} | {
        "paraloop.3mf", "assembly.glb", "animation.glb", "result.json", "report.json",
        "assembly.md", "assembly.html", "paraloop.3dm", "guide_loop.png", "guide_base.png",
        "parts.step", "assembly.step"} | {
        f"guide_joint_{j}.png" for j in range(6)} | {
        f"paraloop_plate{k}.3mf" for k in range(2, plates + 1)}
    assert f"-> {out}: {len(names)} files;" in stdout and "collision-free" in stdout
    assert report["choice"]["note"] in stdout and "peak torque" in stdout
    assert report["verification"]["ok"] and report["verification"]["gap_ok"]
    assert report["walls"]["ok"] and b["stands"] and b["fits_bed"]
    # the parts: closed STLs in the assembled pose (mm), with the report's volumes
    for p in report["parts"]:
        mesh = trimesh.load(out / f"{p['name']}.stl", file_type="stl")
        assert mesh.is_watertight and mesh.volume == pytest.approx(p["volume_cm3"] * 1e3,
                                                                   rel=1e-5)
        assert p["step"] == "exact"  # no end-effector, no carved body (tests/test_step.py)
    # joints: screws with lock nuts, the grounded one on the rod, each held >= 1.5 d
    kinds = [j["kind"] for j in report["joints"]]
    assert kinds.count("rod") == 1 and kinds.count("m3") + kinds.count("dowel") == 5
    assert kinds.index("rod") == b["rod_joint"]
    assert min(min(j["engagement_diameters"]) for j in report["joints"]) >= 1.5
    bom = {row["item"]: row["quantity"] for row in report["bill_of_materials"]}
    screws = [k for k in bom if "socket head cap screw" in k]
    assert sum(bom[k] for k in screws) == kinds.count("m3") >= 1
    assert {float(k.split(" x ")[1].split()[0]) for k in screws} == {
        j["screw_length_mm"] for j in report["joints"] if j["kind"] == "m3"}
    assert bom["M3 nylon-insert lock nut (DIN 985)"] == kinds.count("m3")
    assert any(k.startswith(b["rod"]) for k in bom)


def test_plates_and_assembly_files(exported):
    out, _, _ = exported
    report = json.loads((out / "report.json").read_text())
    bed = np.array(report["print_layout"]["bed_mm"])
    laid = {}
    for f in sorted(out.glob("paraloop*.3mf")):
        scene = trimesh.load(f, file_type="3mf")
        for node in scene.graph.nodes_geometry:
            tf, geom = scene.graph[node]
            laid[node] = scene.geometry[geom].copy().apply_transform(tf)
    assert set(laid) == {p["name"] for p in report["parts"]}
    for name, m in laid.items():
        assert m.bounds[0][2] == pytest.approx(0.0, abs=1e-4)
        assert np.all(m.bounds[0] >= -1e-4) and np.all(m.bounds[1] <= bed + 1e-4), name
        home = trimesh.load(out / f"{name}.stl", file_type="stl")
        assert m.volume == pytest.approx(home.volume, rel=1e-5)
    glb = trimesh.load(out / "assembly.glb", file_type="glb")
    assert len(glb.geometry) > len(laid)  # the parts and the hardware
    doc, blob = read_glb((out / "animation.glb").read_bytes())
    assert len(animated(doc, blob)) == 6
    assert doc["asset"]["extras"]["resting_link"] == report["base"]["grounded_link"]


def test_result_json_is_the_printed_loop(exported):
    """``result.json`` is the printed loop in the format of ``paraloop solve``: its polyline
    scaled by the report's mm per unit is the size the parts were built at, its loop the one
    the report names."""
    out, _, _ = exported
    report = json.loads((out / "report.json").read_text())
    result = json.loads((out / "result.json").read_text())
    assert result["format"] == "paraloop-result" and result["realization"]["status"] == "found"
    assert result["loop"] == report["choice"]["loop"]
    assert result["realization"]["printed"] == report["choice"]["note"]
    pts = np.array(result["realization"]["points"])
    assert np.ptp(pts, axis=0).max() * report["scale_mm_per_unit"] == pytest.approx(
        report["sizing"]["size_mm"])
    real = result["realization"]
    assert real["certified_clearance"] >= 2 * real["radius"]


def test_guide_and_rhino_file(exported):
    out, _, _ = exported
    guide = (out / "assembly.md").read_text()
    for name in ["guide_loop.png", "guide_base.png"] + [f"guide_joint_{j}.png" for j in range(6)]:
        assert f"({name})" in guide
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "lock nut" in guide and "M3" in guide
    import rhino3dm

    model = rhino3dm.File3dm.Read(str(out / "paraloop.3dm"))
    assert model.Settings.ModelUnitSystem == rhino3dm.UnitSystem.Millimeters
    report = json.loads((out / "report.json").read_text())
    assert sorted(layer.Name for layer in model.Layers) == sorted(p["name"]
                                                                 for p in report["parts"])
    for obj in model.Objects:
        stl = trimesh.load(out / f"{obj.Attributes.Name}.stl")
        box = obj.Geometry.GetBoundingBox()
        assert np.allclose([box.Min.X, box.Min.Y, box.Min.Z], stl.bounds[0], atol=1e-4)
        assert np.allclose([box.Max.X, box.Max.Y, box.Max.Z], stl.bounds[1], atol=1e-4)


def test_existing_files_are_refused_before_any_work(exported, capsys, monkeypatch):
    out, _, _ = exported

    def boom(*a, **k):
        raise AssertionError("solved before checking --out")

    monkeypatch.setattr(pipeline, "solve", boom)
    assert main(["export", str(TV8), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "already exists" in err[0] and "--force" in err[0]


def test_force_leaves_one_export(exported, tmp_path, capsys):
    """``--force`` over an earlier export: what this one does not write (a part or picture
    more, the Rhino file) is removed; files that are not an export's are kept."""
    import shutil

    out = tmp_path / "again"
    shutil.copytree(exported[0], out)
    for stale in ("link_9.stl", "guide_joint_9.png", "pin_cap_7.stl"):
        (out / stale).write_bytes(b"old")
    (out / "notes.txt").write_text("mine")
    assert main(["export", str(TV8), "--out", str(out), "--quiet", "--force"]) == 0
    names = {p.name for p in out.iterdir()}
    assert not names & {"link_9.stl", "guide_joint_9.png", "pin_cap_7.stl", "paraloop.3dm"}
    assert "notes.txt" in names and "link_0.stl" in names
    report = json.loads((out / "report.json").read_text())
    assert {p["name"] + ".stl" for p in report["parts"]} <= names


def _refused(argv: list[str], capsys, out: Path, *words: str) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "Traceback" not in err[0], err
    for w in words:
        assert w in err[0], err[0]
    assert not out.exists() or not any(out.iterdir())


def test_print_in_place_is_refused_with_the_reason(tmp_path, capsys):
    out = tmp_path / "pip"
    _refused(["export", str(TV8), "--out", str(out), "--quiet", "--joints", "print-in-place"],
             capsys, out, "print-in-place needs every joint axis within 30 deg",
             "lean up to", "--joints m3")


def test_a_size_too_small_is_refused(tmp_path, capsys):
    out = tmp_path / "small"
    _refused(["export", str(TV8), "--out", str(out), "--quiet", "--size-mm", "40"], capsys,
             out, "at 40 mm", "no realization of this design can be printed")


@pytest.mark.parametrize("bad", [["--size-mm", "nan"], ["--bed", "250,0,210"],
                                 ["--bed", "250,210"], ["--clearance", "-1"],
                                 ["--samples", "4"], ["--joints", "glue"],
                                 ["--printer", "nope"]])
def test_bad_options_are_refused(tmp_path, capsys, bad):
    out = tmp_path / "bad"
    _refused(["export", str(TV8), "--out", str(out), "--quiet", *bad], capsys, out,
             bad[0])
