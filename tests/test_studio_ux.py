"""Headless tests of the studio's newcomer-facing behaviour (issue 15): camera framing, one
notice per cause, Cancel job, relative mesh paths on Load, unit warnings, stale results, the
restore offer and readable labels."""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import numpy as np
import pytest

from app import camera
from app import studio as studio_mod
from app.notices import Notices
from app.panels.design import loop_label, loop_of_label, score_text
from app.state import rescaled
from paraloop_core import design as design_mod
from paraloop_core import pipeline
from tests import test_studio_fabrication
from tests.test_studio_fabrication import open_studio
from tests.test_studio_server import click, gizmo, settle, upload

DESIGNS = Path(__file__).resolve().parent.parent / "assets" / "designs"
tv8 = test_studio_fabrication.tv8  # the fixture: the tv8 example in a headless studio


def project(points, position, look_at, fov, size):
    """Pixel coordinates ``(N, 2)`` of world points seen by a z-up pinhole camera."""
    fwd = (look_at - position) / np.linalg.norm(look_at - position)
    right = np.cross(fwd, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    rel = points - position
    f = 0.5 * size[1] / np.tan(0.5 * fov)
    z = rel @ fwd
    assert np.all(z > 0), "a point is behind the camera"
    return np.stack([0.5 * size[0] + f * (rel @ right) / z,
                     0.5 * size[1] - f * (rel @ up) / z], axis=-1)


def inside_free_view(points, position, look_at, fov, size=camera.DEFAULT_SIZE) -> bool:
    px = project(points, position, look_at, fov, size)
    return bool(np.all((px[:, 0] >= 0) & (px[:, 0] <= size[0] - camera.PANEL_PX)
                       & (px[:, 1] >= 0) & (px[:, 1] <= size[1])))


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("size", [(1280.0, 800.0), (800.0, 900.0), (1920.0, 600.0)])
def test_framing_keeps_every_point_left_of_the_panel(seed, size):
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(200, 3)) * rng.uniform(0.1, 10.0, 3) * 10.0 ** rng.uniform(-3, 4)
    direction = rng.normal(size=3)
    shot = camera.Subject(pts, np.full(len(pts), camera.MARGIN), np.zeros((0, 3, 3)))
    position, look_at = camera.framing(shot, np.radians(75.0), size, direction)
    assert inside_free_view(pts, position, look_at, np.radians(75.0), size)
    # and as close as it gets: the points touch the margin on two opposite sides, or the
    # camera is camera.NEAREST of their extent from the nearest
    px = project(pts, position, look_at, np.radians(75.0), size)
    room = np.array([size[0] - camera.PANEL_PX, size[1]]) * (1 - 2 * camera.MARGIN)
    fwd = (look_at - position) / np.linalg.norm(look_at - position)
    nearest = np.min((pts - position) @ fwd) / np.ptp(pts, axis=0).max()
    assert np.max(np.ptp(px, axis=0) / room) == pytest.approx(1.0, abs=0.01) \
        or nearest == pytest.approx(camera.NEAREST, rel=0.01)


class _Handle:
    def __init__(self, log, text):
        self.log, self.text = log, text

    def remove(self):
        self.log.remove(self.text)


class _Client:
    def __init__(self):
        self.shown: list[str] = []

    def add_notification(self, title, body, **_):
        self.shown.append(title)
        return _Handle(self.shown, title)


class _Server:
    def __init__(self, n):
        self.clients = {i: _Client() for i in range(n)}

    def get_clients(self):
        return self.clients


def test_notices_one_per_cause_and_cleared():
    server = _Server(3)
    notices = Notices(server)
    notices.notify("Cannot solve the design", "a", error=True, cause="solve")
    notices.notify("No collision-free realization", "b", error=True, cause="solve")
    notices.notify("Design loaded", "x.json")
    for c in server.clients.values():
        assert c.shown == ["No collision-free realization", "Design loaded"]
    notices.clear("solve")
    assert all(c.shown == ["Design loaded"] for c in server.clients.values())
    assert len(notices.log) == 3


def test_loop_labels_are_readable():
    label = loop_label(4, 77.3, "ok")
    assert label == "loop 4 · angle-symmetric · score 77" and loop_of_label(label) == 4
    assert "near-singular" in loop_label(2, 3e-7, "near-singular")
    assert [score_text(v) for v in (77.3, 3.41, 0.052, 2e-7)] == ["77", "3.4", "0.052", "2e-07"]


def test_opening_frames_the_object_and_the_free_targets(tv8):
    """The opening camera shows the linkage as drawn and the free target (S3) inside the
    margins; the object (its triangles) covers more of the view than from the old default
    direction at the same fit; *Frame all*'s subject has the path and every target."""
    cam = tv8.server.initial_camera
    shot = tv8.scene.object_shot()
    assert len(shot.triangles) > 0 and tv8.scene.points_home is not None
    at = (np.asarray(cam.position), np.asarray(cam.look_at), cam.fov)
    assert inside_free_view(shot.points, *at)
    assert inside_free_view(tv8.scene.target_positions[[3]], *at)
    view = camera.best_view(shot, cam.fov)
    plain = camera.View(*camera.framing(shot, cam.fov, camera.DEFAULT_SIZE), cam.fov,
                        camera.DEFAULT_SIZE)
    assert camera.screen_area(view, shot.triangles) >= camera.screen_area(plain, shot.triangles)
    everything = tv8.scene.all_shot().points
    assert len(everything) > len(shot.points)


def test_cancel_job_stops_a_carving_and_the_studio_stays_responsive(tv8):
    tv8.fabrication.inputs["resolution"].value = 256
    click(tv8.fabrication.carve)
    end = time.monotonic() + 30
    while tv8.jobs.busy != "carve" and time.monotonic() < end:
        time.sleep(0.01)
    assert tv8.jobs.busy == "carve" and tv8.panels.cancel.visible
    t0 = time.monotonic()  # an edit is drawn while the carving runs on its own thread
    gizmo(tv8, 3, position=tv8.state.design.poses[3].position + 0.01, phases=("update",))
    assert time.monotonic() - t0 < 5.0
    click(tv8.panels.cancel)
    assert tv8.jobs.wait(30) and tv8.worker.wait_idle(30)
    assert tv8.jobs.busy is None and not tv8.panels.cancel.visible
    assert any(t == "Carving cancelled" for t, _, _ in tv8.notifications)
    assert "cancelled" in tv8.fabrication.progress_text.content
    assert not tv8.scene.spaces and tv8.error is None


def test_cancel_job_stops_a_fit():
    server, app = open_studio("sun-path-fit")
    try:
        busy: list[str | None] = []
        app.jobs._on_busy = lambda job, show=app._busy: (busy.append(job), show(job))
        app.state.edit(lambda d: dataclasses.replace(
            d, evolution={**d.evolution, "starts": 400, "workers": 1}))
        app.request(studio_mod.FULL)
        end = time.monotonic() + 30
        while "fit" not in busy and time.monotonic() < end:
            time.sleep(0.005)
        assert "fit" in busy
        click(app.panels.cancel)
        settle(app)
        assert "Fit cancelled" in app.panels.status.content
        assert app.solution is not None and not app.panels.cancel.visible
    finally:
        app.close()
        server.stop()


def test_load_resolves_a_relative_mesh_and_says_one_thing(tv8):
    data = (DESIGNS / "shading-panel.json").read_bytes()
    assert json.loads(data)["end_effector"]["mesh"].startswith("../")
    upload(tv8, "shading-panel.json", data)
    settle(tv8)
    assert tv8.state.design.name == json.loads(data)["name"] and tv8.error is None
    assert tv8.notifications[-1] == ("Design loaded", "shading-panel.json", False)
    assert not any(err for _, _, err in tv8.notifications)
    missing = json.loads(data)
    missing["end_effector"]["mesh"] = "nowhere/none.stl"
    before = tv8.state.design
    upload(tv8, "other.json", json.dumps(missing).encode())
    assert tv8.state.design is before
    title, body, error = tv8.notifications[-1]
    assert error and title == "Cannot load other.json" and "none.stl" in body


def test_unusual_scale_is_flagged_and_rescaled(tv8):
    big = rescaled(tv8.state.design, 1e4)
    upload(tv8, "big.json", json.dumps(design_mod.design_to_dict(big)).encode())
    settle(tv8)
    assert "units" in tv8.panels.details.content and tv8.panels.rescale.visible
    assert "see Rescale" in tv8.panels.status.content
    cam = tv8.server.initial_camera  # framed in the big unit too
    assert inside_free_view(tv8.scene.object_shot().points, np.asarray(cam.position),
                            np.asarray(cam.look_at), cam.fov)
    assert cam.far > np.linalg.norm(np.asarray(cam.position) - np.asarray(cam.look_at))
    click(tv8.panels.rescale)
    settle(tv8)
    assert not tv8.panels.rescale.visible and "units" not in tv8.panels.details.content
    original = design_mod.load_design(DESIGNS / "tv8.json")
    assert np.allclose(tv8.state.design.pose_array[0], original.pose_array[0])
    assert tv8.solution.realization is not None


def test_fabrication_results_are_marked_stale(tv8):
    click(tv8.fabrication.carve)
    assert tv8.worker.wait_idle(60) and tv8.jobs.wait(120) and tv8.worker.wait_idle(60)
    assert tv8.fabrication.bound.content.startswith("**Continuous-motion bound")
    # carved to be seen: the Construction folder's layer is switched on
    assert tv8.panels.layers["Design spaces"].value and "Design spaces" not in tv8.state.hidden
    assert tv8.scene.spaces and all(h.visible for _, h in tv8.scene.spaces)
    gizmo(tv8, 3, position=tv8.state.design.poses[3].position + 0.01)
    assert tv8.fabrication.bound.content.startswith("*(stale")
    assert not any(h.visible for _, h in tv8.scene.spaces)


def test_restore_offer_can_be_discarded(tmp_path):
    autosave = tmp_path / "tv8.json"
    design = design_mod.load_design(DESIGNS / "tv8.json")
    design_mod.save_design(dataclasses.replace(design, name="edited"), autosave)
    server, app = open_studio("tv8", autosave)
    try:
        assert studio_mod.offer_restore(app, None)  # no file: any autosave is offered
        assert app.state.design.name == design.name
        click(app.restore_offer.discard)
        assert not autosave.exists() and app.state.design.name == design.name
    finally:
        app.close()
        server.stop()


def test_a_fit_design_previews_from_one_start_and_fits_fully_on_release():
    """A drag refits one start (preview); the release shows that fit with its certified
    realization at once and asks for the multi-start fit, which replaces it only if it fits
    better (so the result is never worse than the plain multi-start fit of the design)."""
    server, app = open_studio("sun-path-fit")
    try:
        starts = app.state.design.evolution["starts"]
        assert starts > 1 and app.solution.fit.starts_tried == starts
        p = app.state.design.poses[7].position
        gizmo(app, 7, position=p + 0.02, phases=("update",))
        quick = app.solution.fit
        assert quick.starts_tried == 1  # the drag preview
        seen = []
        draw = app._solve_and_draw
        app._solve_and_draw = lambda *a: (draw(*a), seen.append((
            a[2], app.solution.fit, app.solution.realization, app.panels.details.content)))
        gizmo(app, 7, position=p + 0.02, phases=("end",))
        (lvl1, fit1, real1, status1), (lvl2, fit2, _, status2) = seen
        assert (lvl1, lvl2) == (studio_mod.FULL, studio_mod.REFINE)
        assert fit1 is quick and real1 is not None and "refining it with" in status1
        cold = pipeline.solve(app.state.design, realize=False).fit
        assert fit2.cost <= min(quick.cost, cold.cost) * (1 + 1e-9)
        assert "refining" not in status2 and app.solution.realization is not None
    finally:
        app.close()
        server.stop()


def test_no_restore_offer_when_the_autosave_equals_the_file(tmp_path):
    autosave = tmp_path / "tv8.json"
    design_mod.save_design(design_mod.load_design(DESIGNS / "tv8.json"), autosave)
    server, app = open_studio("tv8", autosave)
    try:
        assert studio_mod.offer_restore(app, None) is None and app.restore_offer is None
    finally:
        app.close()
        server.stop()


def test_a_bug_in_a_background_job_is_notified(tv8, monkeypatch):
    def broken(task, arg):
        raise RuntimeError("boom")

    monkeypatch.setattr(tv8.fabrication, "run", broken)
    click(tv8.fabrication.carve)
    assert tv8.worker.wait_idle(30) and tv8.jobs.wait(30)
    assert tv8.notifications[-1][0] == "Internal error" and "boom" in tv8.notifications[-1][1]
    assert tv8.jobs.busy is None and not tv8.panels.cancel.visible


@pytest.mark.parametrize("drag_fit_wins", [False, True])
def test_a_fit_release_whose_quick_search_misses_ends_realized(monkeypatch, drag_fit_wins):
    """A fit design's quick update without a realization (the quick search missed): REFINE
    runs the multi-start fit and the full search, also when the drag's fit stays the better
    one (forced here by making the multi-start fit look worse); the studio ends realized,
    never "searching" for ever, and never caches an incomplete search."""
    from app import solver as solver_mod

    monkeypatch.setattr(solver_mod, "QUICK_WORK", 1)
    monkeypatch.setattr(pipeline, "PREVIEW_WORK", 1)
    server, app = open_studio("sun-path-fit")
    try:
        seen = []
        draw = app._solve_and_draw
        app._solve_and_draw = lambda *a: (draw(*a), seen.append((
            a[2], app.solution.realization, app.panels.status.content)))
        completed = []
        full_search, solve = app.solver.complete, app.solver.solve
        monkeypatch.setattr(app.solver, "complete",
                            lambda *a, **k: completed.append(1) or full_search(*a, **k))

        def worse_refit(design, full, current, progress=None, **kw):
            sol, note = solve(design, full, current, progress, **kw)
            if drag_fit_wins and progress is not None:  # the REFINE's multi-start fit
                sol = dataclasses.replace(sol, fit=dataclasses.replace(
                    sol.fit, cost=10 * sol.fit.cost + 1.0))
            return sol, note

        monkeypatch.setattr(app.solver, "solve", worse_refit)
        p = app.state.design.poses[7].position
        gizmo(app, 7, position=p + 0.3, phases=("update",))  # the preview's one-start fit
        gizmo(app, 7, position=p + 0.3, phases=("end",))
        first = next(s for lvl, _, s in seen if lvl == studio_mod.FULL)
        assert "Searching for a collision-free loop" in first
        lvl, real, status = seen[-1]
        assert lvl == studio_mod.REFINE and real is not None
        assert "Searching" not in status and "Collision-free loop found" in status
        assert not solver_mod.incomplete(app.solution)
        # the drag's fit with a complete search would also do: never an incomplete cache
        assert all(not solver_mod.incomplete(s) for s, _ in app.solver._cache.values())
        assert len(completed) == int(drag_fit_wins)
    finally:
        app.close()
        server.stop()
