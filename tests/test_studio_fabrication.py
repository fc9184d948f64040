"""Headless tests of the studio's Fabrication folder: settings validation, carving design
spaces in the worker (meshes, animation, the bound text), the export zip and its failures."""

from __future__ import annotations

import io
import json
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
import viser
from test_studio_server import click, gizmo, settle

from app import studio as studio_mod
from app.exports import carve_order, options_of, parse_order, size_of
from app.panels.fabrication import check_setting
from app.state import FabSettings
from paraloop_core import design as design_mod
from paraloop_core.algebra import dq, poly
from paraloop_core.fabrication import profiles
from paraloop_core.linkage import loops

DESIGNS = Path(__file__).resolve().parent.parent / "assets" / "designs"
#: what every export zip holds besides the parts' STLs and further plates
FIXED_FILES = {"paraloop-result.json", "paraloop.3mf", "assembly.glb", "animation.glb",
               "report.json", "result.json", "assembly.md", "assembly.html", "guide_loop.png",
               "guide_base.png", "parts.step", "assembly.step"} | {
    f"guide_joint_{j}.png" for j in range(6)}


def open_studio(name: str, autosave=None):
    """A headless studio on the bundled example ``name``, settled."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = studio_mod.Studio(server, design_mod.load_design(DESIGNS / f"{name}.json"),
                            autosave)
    settle(app)
    return server, app


@pytest.fixture
def tv8():
    server, app = open_studio("tv8")
    yield app
    app.close()
    server.stop()


@pytest.fixture
def sun():
    server, app = open_studio("sun-disc")
    yield app
    app.close()
    server.stop()


def wait_long(app, seconds: float = 120.0) -> None:
    """The worker idle and the background job (carve / export) it started finished."""
    assert app.worker.wait_idle(seconds) and app.jobs.wait(seconds)
    assert app.worker.wait_idle(seconds)


def test_settings_are_validated(tv8):
    inputs = tv8.fabrication.inputs
    assert tv8.state.fab.size_mm == 0.0 and "0 = automatic" in inputs["size_mm"].hint
    inputs["size_mm"].value = -5.0
    title, body, error = tv8.notifications[-1]
    assert error and "must be >= 0 mm" in body and tv8.state.fab.size_mm == 0.0
    settle(tv8)
    assert inputs["size_mm"].value == 0.0  # the kept value is written back
    inputs["clearance_mm"].value = -0.1
    assert tv8.notifications[-1][2] and tv8.state.fab.clearance_mm == 0.3
    inputs["clearance_mm"].value = 0.0
    inputs["size_mm"].value = 250.0
    inputs["print_in_place"].value = True
    assert tv8.state.fab == FabSettings(size_mm=250.0, clearance_mm=0.0, print_in_place=True)
    inputs["custom_order"].value = "0-1, 1-0"
    assert "twice" in tv8.notifications[-1][1] and tv8.state.fab.custom_order == ""


def test_printer_and_bed_reach_the_export_options(tv8):
    """The printer profile and a build volume (what a refused export names) are the
    export's, as ``--printer`` and ``--bed`` are the command line's; a malformed bed is
    refused with what is accepted and the profile's bed kept."""
    inputs = tv8.fabrication.inputs
    assert options_of(tv8.state.fab).printer.bed_mm == (250.0, 210.0, 210.0)
    inputs["printer"].value = "prusa-mini"
    inputs["bed"].value = "375, 315,315"
    printer = options_of(tv8.state.fab).printer
    assert printer.bed_mm == (375.0, 315.0, 315.0) and printer.clearance_mm == 0.3
    assert printer.wall_mm == profiles.PRINTERS["prusa-mini"].wall_mm
    for bad in ("375,315", "375,0,315", "big"):
        inputs["bed"].value = bad
        title, body, error = tv8.notifications[-1]
        assert error and "X,Y,Z in mm" in body and tv8.state.fab.bed == "375, 315,315"
    inputs["bed"].value = ""
    assert options_of(tv8.state.fab).printer.bed_mm == (180.0, 180.0, 180.0)


def test_order_presets_and_parsing():
    for preset in ("base first", "end first"):
        pairs = carve_order(FabSettings(order=preset))
        assert len({frozenset(p) for p in pairs}) == 15
    assert carve_order(FabSettings(order="end first"))[0] == (3, 2)
    text = ", ".join(f"{b}-{a}" for a in range(6) for b in range(a + 1, 6))
    assert parse_order(text)[0] == (1, 0)
    for bad, why in (("0-1", "all 15"), ("0-0", "differ"), ("0+1", "target-source")):
        with pytest.raises(ValueError, match=why):
            parse_order(bad)
    with pytest.raises(ValueError, match="16..256"):
        check_setting("resolution", 8)
    assert check_setting("space_radius_mm", "0") == 0.0


def test_carve_draws_animated_spaces_and_the_bound(sun):
    fab = sun.fabrication
    click(fab.carve)
    wait_long(sun)  # bounded wait: a hang fails here (speed is measured in benchmarks/)
    scene = sun.scene
    assert len(scene.spaces) == 6 and all(h.visible for _, h in scene.spaces), sun.notifications
    size = size_of(sun.solution, sun.state.fab)  # automatic: the printer's
    assert size >= 150.0 and f" mm at {size:.0f} mm" in fab.bound.content
    assert "Continuous-motion bound" in fab.bound.content
    assert "approximate" in fab.bound.content
    margin = fab.carving["max_motion_margin"]
    assert margin > 0 and f"{margin:.3g}" in fab.bound.content
    fractions = [f for _, f in fab.progress_log]
    assert fractions[-1] == 1.0 and fractions == sorted(fractions) and len(fractions) > 5
    assert not fab.progress.visible
    # the spaces move with their links (motion slider)
    sun.panels.u.value = 0.37
    settle(sun)
    links = loops.link_poses(sun.solution.loop.joint_factors, poly.param_to_t(np.array([0.37])))
    pos, wxyz = dq.to_pos_wxyz(links[0])
    for i, handle in scene.spaces:
        assert np.allclose(handle.position, pos[i], atol=1e-5)
        assert np.allclose(np.abs(handle.wxyz @ wxyz[i]), 1.0, atol=1e-5)
    sun.panels.layers["Design spaces"].value = False  # the Construction folder's box
    settle(sun)
    assert not any(h.visible for _, h in scene.spaces)
    sun.panels.layers["Design spaces"].value = True
    settle(sun)
    assert all(h.visible for _, h in scene.spaces)
    # a new loop makes them stale: hidden until carved again
    gizmo(sun, 3, position=sun.state.design.poses[3].position + 0.02)
    assert sun.error is None and not any(h.visible for _, h in scene.spaces)


def test_carving_is_cancelled_by_a_design_edit(tv8):
    tv8.fabrication.inputs["resolution"].value = 32
    click(tv8.fabrication.carve)
    end = time.monotonic() + 30
    while not tv8.fabrication.progress_log and time.monotonic() < end:
        time.sleep(0.01)
    p = tv8.state.design.poses[3]
    assert tv8.state.move_pose(3, p.position + 0.01, p.wxyz, commit=True)
    wait_long(tv8)
    assert any(t == "Carving cancelled" for t, _, _ in tv8.notifications)
    assert not tv8.scene.spaces and tv8.error is None


def test_export_zip_has_parts_and_a_verified_report(tv8):
    click(tv8.fabrication.export)
    wait_long(tv8)
    name, data = tv8.downloads[-1]
    assert name.startswith("paraloop-TV8") and name.endswith(".zip"), tv8.notifications
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        names = set(zf.namelist())
        report = json.loads(zf.read("report.json"))
        result = json.loads(zf.read("paraloop-result.json"))
        printed = json.loads(zf.read("result.json"))
        plates = report["print_layout"]["plates"]
        assert names == FIXED_FILES | {f"{p['name']}.stl" for p in report["parts"]} | {
            f"paraloop_plate{k}.3mf" for k in range(2, plates + 1)}
        assert zf.read("assembly.glb")[:4] == b"glTF" and len(zf.read("link_0.stl")) > 1000
    # the design's result, and the printed loop's (realized again for real joints)
    assert result["format"] == printed["format"] == "paraloop-result"
    assert printed["loop"] == report["choice"]["loop"]
    ver, sz = report["verification"], report["sizing"]
    assert ver["ok"] and report["walls"]["ok"] and sz["printer"] == "generic"
    assert report["base"]["stands"] and all(p["fits_bed"] for p in
                                            report["print_layout"]["parts"])
    assert tv8.fabrication.report == report
    text = tv8.fabrication.verification.content
    assert f"**Size {sz['size_mm']:.0f} mm**" in text and "ok" in text
    assert f"{min(sz['bar_width_mm']):.1f} - {max(sz['bar_width_mm']):.1f} mm wide" in text
    assert f"{ver['min_non_adjacent_gap_mm']:.1f} mm over the whole cycle" in text
    assert report["choice"]["note"] in text and "stands on its base" in text


def test_export_failures_keep_the_design(tv8):
    before, sol = tv8.state.design, tv8.solution
    n = len(tv8.downloads)
    tv8.fabrication.inputs["size_mm"].value = 50.0  # valid input, too small for the bars
    click(tv8.fabrication.export)
    wait_long(tv8)
    title, body, error = tv8.notifications[-1]
    # every candidate named with why it does not fit at that size
    assert error and title == "Export failed" and "at 50 mm" in body
    assert "no realization of this design can be printed with real joints" in body
    assert len(tv8.downloads) == n and not tv8.fabrication.progress.visible
    assert tv8.state.design is before and tv8.solution is sol and tv8.error is None
    # without a realization: the result JSON only, and a notification saying so
    tv8.panels.real["enabled"].value = False
    settle(tv8)
    click(tv8.fabrication.export)
    wait_long(tv8)
    name, data = tv8.downloads[-1]
    assert zipfile.ZipFile(io.BytesIO(data)).namelist() == ["paraloop-result.json"]
    assert tv8.notifications[-1][0] == "Exported the result only"
    click(tv8.fabrication.carve)
    wait_long(tv8)
    assert "no realization" in tv8.notifications[-1][1] and not tv8.scene.spaces


def test_print_in_place_is_refused_with_the_reason(tv8):
    n = len(tv8.downloads)
    tv8.fabrication.inputs["print_in_place"].value = True
    click(tv8.fabrication.export)
    wait_long(tv8)
    title, body, error = tv8.notifications[-1]
    assert error and title == "Export failed" and "print-in-place needs" in body
    # in the studio's words: its own control, no command-line option
    assert "switch off Print in place" in body and "--" not in body
    assert len(tv8.downloads) == n
