"""Headless tests of the studio: drive GUI handles and gizmo callbacks from Python and check
the state, the scene handles, notifications and downloads (no browser)."""

from __future__ import annotations

import asyncio
import dataclasses
import hashlib
import json
import os
import time
from pathlib import Path

import numpy as np
import pytest
import viser
from viser._gui_handles import GuiEvent, UploadedFile

from app import studio as studio_mod
from app.panels.design import loop_label
from app.scene import FACTOR_COLORS
from app.worker import FULL, PREVIEW
from paraloop_core import design as design_mod
from paraloop_core.algebra import dq, poly
from paraloop_core.linkage import loops

DESIGN = Path(__file__).resolve().parent.parent / "assets" / "designs" / "tv8.json"


@pytest.fixture
def studio(tmp_path):
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    design = dataclasses.replace(design_mod.load_design(DESIGN), locked=(0, 1, 2))
    app = studio_mod.Studio(server, design, tmp_path / "tv8.autosave.json")
    assert app.worker.wait_idle(30)
    yield app
    app.close()
    server.stop()


def settle(app) -> None:
    assert app.worker.wait_idle(30)


def gizmo(app, i: int, position=None, wxyz=None, phases=("start", "update", "end")) -> None:
    """What a browser drag does: set the gizmo pose and fire its callbacks per phase."""
    g = app.scene.gizmos[i]
    for phase in phases:
        if position is not None:
            g.position = np.asarray(position, float)
        if wxyz is not None:
            g.wxyz = np.asarray(wxyz, float)
        for cb in list(g._impl_aux.update_cb):
            asyncio.run(cb(viser.TransformControlsEvent(None, None, g, phase)))
    settle(app)


def click(button) -> None:
    button.value = True  # buttons fire their callbacks synchronously when set from Python


def upload(app, name: str, content: bytes, handle=None) -> None:
    """What a browser upload does (default: the *Load design* button)."""
    handle = handle or app.panels.load
    handle._impl.value = UploadedFile(name, content)
    for cb in list(handle._impl.update_cb):
        cb(GuiEvent(client=None, client_id=None, target=handle))
    settle(app)


def pose_error(sol, i: int) -> float:
    """Distance of C(t_i) from target i (position and rotation)."""
    p = sol.design.poses[i]
    q = poly.evaluate_pose(sol.motion, sol.pose_parameters[i])
    pos, wxyz = dq.to_pos_wxyz(q)
    return float(np.linalg.norm(pos - p.position) + min(np.linalg.norm(wxyz - p.wxyz),
                                                       np.linalg.norm(wxyz + p.wxyz)))


def test_startup_draws_everything(studio):
    sol = studio.solution
    assert studio.error is None and sol is not None
    assert len(studio.scene.gizmos) == 4
    h = studio.scene.handles
    assert h["path"].points.shape == (256, 2, 3)
    assert h["facts"].points.shape == (18, 2, 3)
    assert np.array_equal(h["facts"].colors[::3, 0], FACTOR_COLORS)
    assert h["bars"].batched_positions.shape == (6, 3) and h["joints"].visible
    # the trajectory passes through every target (visit labels in order)
    for i in range(4):
        assert pose_error(sol, i) < 1e-6
    labels = [lb.text for lb in studio.scene.labels]
    assert labels[0].startswith("S0 #1") and sorted(s.split()[1] for s in labels) == \
        ["#1", "#2", "#3", "#4"]
    assert "score" in studio.panels.loop.options[0] and "ok" in studio.panels.status.content
    if sol.realization is not None:  # the certified radii (docs/result-format.md)
        assert "certified thickest: every bar and pin" in studio.panels.status.content
    x = studio.plots.angles.data[0]
    assert x.shape == (241,) and np.allclose(np.diff(x), 360 / 242)  # uniform driving angle


def test_gizmo_drag_previews_then_commits(studio):
    before = studio.scene.handles["path"].points.copy()
    undo = len(studio.state.undo_stack)
    new = studio.state.design.poses[3].position + np.array([0.05, -0.03, 0.02])
    gizmo(studio, 3, position=new, phases=("start", "update"))
    assert studio._drawn[1] == PREVIEW and len(studio.state.undo_stack) == undo
    assert np.allclose(studio.state.design.poses[3].position, new)
    assert not np.allclose(studio.scene.handles["path"].points, before, atol=1e-4)
    assert pose_error(studio.solution, 3) < 1e-6
    gizmo(studio, 3, position=new, phases=("end",))
    assert studio._drawn[1] == FULL and len(studio.state.undo_stack) == undo + 1
    # undo restores the pose, the gizmo and the motion
    click(studio.panels.undo)
    settle(studio)
    assert np.allclose(studio.scene.gizmos[3].position, design_mod.load_design(DESIGN)
                       .poses[3].position)
    assert np.allclose(studio.scene.handles["path"].points, before, atol=1e-5)
    click(studio.panels.redo)
    settle(studio)
    assert np.allclose(studio.scene.gizmos[3].position, new)


def test_locked_pose_ignores_drags(studio):
    old = studio.state.design.poses[1].position.copy()
    gizmo(studio, 1, position=old + 0.2)
    assert np.allclose(studio.state.design.poses[1].position, old)
    assert np.allclose(studio.scene.gizmos[1].position, old)  # snapped back
    # unlocking through the checkbox lets it move; locking all four is refused
    studio.panels.locks[1].value = False
    settle(studio)
    assert studio.state.design.locked == (0, 2)
    gizmo(studio, 1, position=old + 0.05)
    assert np.allclose(studio.state.design.poses[1].position, old + 0.05)
    studio.panels.locks[1].value = True
    studio.panels.locks[3].value = True
    settle(studio)
    assert studio.state.design.locked == (0, 1, 2)
    assert not studio.panels.locks[3].value and studio.notifications[-1][2]


def test_status_is_not_ok_without_a_realization(studio, monkeypatch):
    """A solved design whose loop is not realized: the status says so, not "ok"."""
    from app import solver as solver_mod
    from paraloop_core import pipeline

    monkeypatch.setattr(pipeline, "FIRST_ATTEMPT_WORK", 1)
    monkeypatch.setattr(pipeline, "FALLBACK_WORK", 1)
    monkeypatch.setattr(pipeline, "PREVIEW_WORK", 1)  # no pattern from a drag preview either
    monkeypatch.setattr(solver_mod, "QUICK_WORK", 1)
    p = studio.state.design.poses[3]
    gizmo(studio, 3, position=np.asarray(p.position) + 0.013)
    assert studio.solution.realization is None and studio.error is None
    text = studio.panels.status.content
    assert "no collision-free realization" in text and "ok" not in text.split("(")[0] \
        and "budget" in text and "faint" in text
    assert studio.scene.handles["ghost"].visible  # the last realized linkage, faint
    monkeypatch.undo()
    click(studio.panels.undo)
    settle(studio)
    assert studio.solution.realization is not None and "**Status:** ok" in \
        studio.panels.status.content


def test_failure_keeps_last_valid_design(studio):
    valid = studio.solution
    s0 = studio.state.design.poses[0]
    gizmo(studio, 3, position=s0.position, wxyz=s0.wxyz)  # coincides with S_0
    assert studio.error and studio.solution is valid
    title, body, error = studio.notifications[-1]
    assert error and "Cannot solve" in title and "last valid" in body
    assert "⚠" in studio.panels.status.content
    click(studio.panels.undo)
    settle(studio)
    assert studio.error is None and studio.solution.motion is valid.motion  # from the cache


def test_name_edits_reuse_the_solution(studio):
    motion, undo = studio.solution.motion, len(studio.state.undo_stack)
    studio.panels.name.value = "renamed"
    studio.panels.name.value = "renamed again"
    settle(studio)
    assert studio.solution.design.name == "renamed again" and studio.solution.motion is motion
    assert len(studio.state.undo_stack) == undo + 1


def test_internal_errors_are_notified(studio, monkeypatch):
    def broken(*args, **kwargs):
        raise ZeroDivisionError("boom")

    monkeypatch.setattr(studio.scene, "draw_frame", broken)
    studio.panels.u.value = 0.2
    settle(studio)
    assert studio.notifications[-1][0] == "Internal error" and studio.worker.jobs_run > 0


def test_loop_picker_switches_loop(studio):
    old = studio.scene.handles["axes"].points.copy()
    studio.panels.loop.value = studio.panels.loop.options[4]
    settle(studio)
    sol = studio.solution
    assert studio.state.design.loop == 4 and sol.design.loop == 4
    f, g = loops.LOOP_PAIRS[4]
    colors = studio.scene.handles["axes"].colors[:, 0]
    assert np.array_equal(colors[0], FACTOR_COLORS[f]) and np.array_equal(colors[5],
                                                                          FACTOR_COLORS[g])
    assert not np.allclose(studio.scene.handles["axes"].points, old)
    assert studio.panels.loop.value.startswith(loop_label(4))


def test_motion_slider_moves_linkage(studio):
    bars = studio.scene.handles["bars"].batched_positions.copy()
    studio.panels.u.value = 0.3
    settle(studio)
    sol = studio.solution
    pos, _ = dq.to_pos_wxyz(poly.evaluate_pose(sol.motion, poly.param_to_t(0.3)))
    assert np.allclose(studio.scene.handles["current"].position, pos, atol=1e-5)
    assert not np.allclose(studio.scene.handles["bars"].batched_positions, bars, atol=1e-4)
    # the end link (3) moves rigidly with the motion: its bar keeps its distance to the frame
    home = studio.scene.points_home[6:8].mean(0)
    moved = dq.transform_points(poly.evaluate_pose(sol.monic, poly.param_to_t(0.3)), home)
    assert np.allclose(studio.scene.handles["bars"].batched_positions[3], moved, atol=1e-4)


def test_view_layers(studio):
    studio.panels.layers["Factorization axes"].value = False
    studio.panels.layers["Linkage"].value = False
    settle(studio)
    h = studio.scene.handles
    assert not h["facts"].visible and not h["bars"].visible and not h["joints"].visible
    assert h["path"].visible
    studio.panels.layers["Linkage"].value = True
    settle(studio)
    assert h["bars"].visible and not h["facts"].visible
    radius = h["bars"].batched_scales[0, 0]
    studio.panels.thickness.value = 3.0
    settle(studio)
    assert h["bars"].batched_scales[0, 0] == pytest.approx(3 * radius)


def test_linkage_stays_closed_over_the_cycle(studio):
    pts = studio.scene.points_home
    jf = studio.solution.loop.joint_factors
    for u in (0.1, 0.45, 0.8):
        studio.panels.u.value = u
        settle(studio)
        links = loops.link_poses(jf, poly.param_to_t(np.array([u])))[0]
        e = dq.transform_points(links, pts[1::2])  # E_i carried by link i
        s_next = dq.transform_points(np.roll(links, -1, axis=0), np.roll(pts[0::2], -1, axis=0))
        e_next = dq.transform_points(np.roll(links, -1, axis=0), pts[1::2])  # ... and by i+1
        assert np.allclose(e, e_next, atol=1e-9)
        assert np.allclose(studio.scene.handles["joints"].batched_positions, 0.5 * (e + s_next),
                           atol=1e-5)
        # the pins lie on the animated loop axes
        axes = loops.axes_at(jf, poly.param_to_t(np.array([u])))[0]
        dist = np.linalg.norm(np.cross(e, axes[:, :3]) - axes[:, 3:], axis=-1)
        assert np.all(dist < 1e-9)


def test_play_advances_u(studio):
    studio.panels.speed.value = 1.0
    studio.panels.play.value = True
    time.sleep(0.4)
    studio.panels.play.value = False
    assert 0.1 < studio.state.u < 0.9
    assert abs(studio.panels.u.value - studio.state.u) < 0.05


def test_mu_slider_and_merged_history(studio):
    undo = len(studio.state.undo_stack)
    studio.panels.mu.value = 0.6
    studio.panels.mu.value = 0.62
    settle(studio)
    assert len(studio.state.undo_stack) == undo + 1
    assert studio.state.design.motion.mu == pytest.approx(0.62)
    assert studio.solution.mu == pytest.approx(0.62) and not studio.panels.mu_inf.value
    studio.panels.mu_inf.value = True  # the family's motion at mu = infinity
    settle(studio)
    assert studio.state.design.motion.mu is None and studio.solution.mu is None
    studio.panels.family.value = "1"
    settle(studio)
    assert studio.solution.design.motion.family == 1 or studio.error


def test_best_mu_button(studio):
    studio.panels.criterion.value = "length"
    click(studio.panels.best_mu)
    settle(studio)
    sol = studio.solution
    assert studio.error is None and sol.design.motion.criterion == "length"
    # the slider shows the mu the criterion chose, in the same unit as the design file
    assert studio.panels.mu_inf.value == (sol.mu is None)
    assert sol.mu is None or studio.panels.mu.value == pytest.approx(sol.mu, abs=1e-3)
    # dragging previews with the last mu (no scan); the release re-runs the criterion
    new = studio.state.design.poses[3].position + 0.02
    gizmo(studio, 3, position=new, phases=("update",))
    assert studio.solution.design.motion.criterion is None and studio.solution.mu == sol.mu
    gizmo(studio, 3, position=new, phases=("end",))
    assert studio.solution.design.motion.criterion == "length"


def test_save_export_and_upload(studio, tmp_path):
    click(studio.panels.save)
    name, data = studio.downloads[-1]
    assert name.endswith(".json")
    saved = design_mod.design_from_dict(json.loads(data))
    assert np.allclose(saved.pose_array[0], studio.state.design.pose_array[0])
    click(studio.panels.export)
    settle(studio)  # built on the worker
    name, data = studio.downloads[-1]
    result = json.loads(data)
    assert name == "paraloop-result.json" and result["format"] == "paraloop-result"
    assert len(result["loops"]) == 9
    click(studio.panels.animation)  # the realized loop over one cycle, animated glTF
    settle(studio)
    name, data = studio.downloads[-1]
    assert name.endswith("-cycle.glb") and data[:4] == b"glTF" and len(data) > 10_000
    # a broken file: error notification, design kept
    before = studio.state.design
    upload(studio, "broken.json", b'{"format": "paraloop-design", "poses": [1, 2]}')
    title, body, error = studio.notifications[-1]
    assert error and "broken.json" in title and "poses" in body
    assert studio.state.design is before
    upload(studio, "junk.json", b"\x00not json")
    assert studio.notifications[-1][2] and studio.state.design is before
    # a good file with moved poses replaces the design (undoable)
    d = design_mod.design_to_dict(before)
    d["name"] = "uploaded"
    d["poses"][3]["position"] = [0.7, 0.5, 0.8]
    opened = studio.state.autosave_path
    upload(studio, "good.json", json.dumps(d).encode())
    assert studio.state.design.name == "uploaded" and studio.panels.name.value == "uploaded"
    # its own autosave: the opened file's unsaved work is not overwritten
    assert studio.state.autosave_path != opened
    # keyed by content: another upload named good.json gets another autosave
    key = hashlib.sha256(json.dumps(d).encode()).hexdigest()[:12]
    assert studio.state.autosave_path.name == f"upload-good-{key}.json"
    assert np.allclose(studio.scene.gizmos[3].position, [0.7, 0.5, 0.8])
    assert studio.error is None and studio.solution.design.name == "uploaded"


def test_upload_rescaled_design_rebuilds_scene(studio):
    d = design_mod.design_to_dict(studio.state.design)
    for p in d["poses"]:
        p["position"] = [10 * x for x in p["position"]]
    upload(studio, "big.json", json.dumps(d).encode())
    assert studio.error is None and studio.scene.scale > 20
    assert studio.scene.gizmos[3].scale == pytest.approx(0.3 * studio.scene.scale)
    assert np.abs(studio.scene.handles["path"].points).max() > 5
    studio.panels.u.value = 0.5
    settle(studio)


def test_add_and_remove_pose(studio):
    studio.panels.locks[0].value = False
    settle(studio)
    click(studio.panels.add_pose)
    settle(studio)
    assert len(studio.state.design.poses) == 5 and len(studio.scene.gizmos) == 5
    assert len(studio.panels.locks) == 5 and studio.error  # four-pose needs exactly 4
    assert studio.scene.handles["path"].visible  # the last valid design stays on screen
    assert studio.notifications[-1][2]
    studio.panels.pose_pick.value = "S4"
    click(studio.panels.remove_pose)
    settle(studio)
    assert len(studio.scene.gizmos) == 4 and studio.error is None


def test_autosave_and_restore(studio, tmp_path):
    path = studio.state.autosave_path
    # an unfinished drag (no release) is on disk within 2 s
    gizmo(studio, 3, position=[0.6, 0.5, 0.8], phases=("start", "update"))
    end = time.monotonic() + 2.0
    while time.monotonic() < end and not (
            path.exists() and np.allclose(design_mod.load_design(path).poses[3].position,
                                          [0.6, 0.5, 0.8])):
        time.sleep(0.05)
    assert np.allclose(design_mod.load_design(path).poses[3].position, [0.6, 0.5, 0.8])
    gizmo(studio, 3, position=[0.6, 0.5, 0.8], phases=("end",))
    # a new session on the same file offers the autosave; undo returns to the file
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    again = studio_mod.Studio(server, design_mod.load_design(DESIGN), path)
    try:
        os.utime(path, (time.time() + 5, time.time() + 5))
        msg = studio_mod.offer_restore(again, DESIGN)
        settle(again)
        assert msg and "offers to restore" in msg
        offer = again.restore_offer
        assert offer.restore.label.startswith("Restore changes from ")
        assert np.allclose(again.state.design.poses[3].position, [0.64, 0.48, 0.8])  # not yet
        click(offer.restore)
        settle(again)
        assert np.allclose(again.scene.gizmos[3].position, [0.6, 0.5, 0.8])
        click(again.panels.undo)
        settle(again)
        assert np.allclose(again.state.design.poses[3].position, [0.64, 0.48, 0.8])
    finally:
        again.close()
        server.stop()


def test_realization_panel_and_clearance_plot(studio):
    real = studio.solution.realization
    assert real is not None
    assert np.allclose(studio.scene.points_home, real.points)
    u, clearance, twice_rho = studio.plots.clearance.data
    assert studio.plots.clearance.visible and np.all(clearance >= 2 * real.radius - 1e-9)
    assert clearance.min() == pytest.approx(real.min_clearance, rel=1e-6)
    studio.panels.real["p"].value = 8.0
    settle(studio)
    assert studio.solution.design.realization.p == 8.0 and studio.solution.realization.p == 8.0
    studio.panels.real["fixed"].value = "0=0.1, 9=1"
    assert studio.notifications[-1][2] and studio.state.design.realization.fixed == {}
    studio.panels.real["enabled"].value = False
    settle(studio)
    assert studio.solution.realization is None and not studio.plots.clearance.visible
    assert np.allclose(studio.scene.handles["bars"].batched_scales[:, 0], 0.01 * studio.scene.scale)


@pytest.mark.parametrize("path", sorted(DESIGN.parent.glob("*.json")), ids=lambda p: p.stem)
def test_every_example_opens(path):
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = studio_mod.Studio(server, design_mod.load_design(path), None)
    try:
        settle(app)
        assert app.error is None and not app.notifications
        assert "bars" in app.scene.handles and len(app.scene.gizmos) == len(app.state.design.poses)
    finally:
        app.close()
        server.stop()


def test_a_release_the_quick_search_misses_is_searched_fully_in_the_background(
        studio, monkeypatch):
    """The release draws at once (status: searching) and the full search, a job, then
    delivers the certified realization; an edit during the search supersedes it."""
    from app import solver as solver_mod
    from paraloop_core import pipeline

    monkeypatch.setattr(pipeline, "PREVIEW_WORK", 1)
    monkeypatch.setattr(solver_mod, "QUICK_WORK", 1)
    lines = []
    real = studio_mod.status_line
    monkeypatch.setattr(studio_mod, "status_line",
                        lambda sol, **kw: lines.append(real(sol, **kw)) or lines[-1])
    refined = len(studio.timings[studio_mod.REFINE])
    p = studio.state.design.poses[3]
    gizmo(studio, 3, position=np.asarray(p.position) + 0.3)  # too far for the warm start
    assert any("searching for a collision-free realization" in s for s in lines)
    assert len(studio.timings[studio_mod.REFINE]) == refined + 1
    sol = studio.solution
    assert sol.realization is not None and "**Status:** ok" in studio.panels.status.content
    assert sol.realization.certified_clearance >= 2 * sol.realization.radius
    assert not sol.realization_report.get("incomplete")
    # cached once complete: undo and redo return it without a search
    click(studio.panels.undo)
    settle(studio)
    click(studio.panels.redo)
    settle(studio)
    assert studio.solution.realization is sol.realization
    # the slider moves during a search: the frame is redrawn from inside it
    frames = []
    monkeypatch.setattr(studio.scene, "draw_frame", lambda u, th: frames.append(u))
    studio._busy_frame = (0.0, ())
    studio.state.u = 0.37
    studio._frame_while_busy()
    assert frames == [0.37]
    monkeypatch.undo()
    monkeypatch.setattr(pipeline, "PREVIEW_WORK", 1)
    monkeypatch.setattr(solver_mod, "QUICK_WORK", 1)
    # a job superseded by an edit: the check raises as soon as the design changes
    checks = []

    def slow_solve(design, *args, check=None, **kw):
        checks.append(check)
        if check is not None:
            studio.state.version += 1  # what an edit during the search does
            check()
        return orig(design, *args, check=check, **kw)

    orig = studio.solver.solve
    monkeypatch.setattr(studio.solver, "solve", slow_solve)
    gizmo(studio, 3, position=np.asarray(p.position) - 0.3)
    assert any(c is not None for c in checks)  # the job ran, was stopped, drew nothing
    assert "searching for a collision-free realization" in studio.panels.status.content
