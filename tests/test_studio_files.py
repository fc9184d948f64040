"""Headless tests of the studio's files: Save, Export, Animation, Load design (stale scene
nodes, one notice per load), the autosave (in the user state folder, on disk within 2 s of
an edit even while a realization search runs) and the restore offer."""

from __future__ import annotations

import hashlib
import json
import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import viser

from app import solver as solver_mod
from app import studio as studio_mod
from app.notices import LOAD
from app.state import autosave_dir, autosave_path_for, legacy_autosave_dir, migrate_autosave
from paraloop_core import design as design_mod
from paraloop_core import pipeline
from tests import test_studio_server
from tests.test_studio_server import DESIGN, click, gizmo, settle, upload

DESIGNS = Path(__file__).resolve().parent.parent / "assets" / "designs"
studio = test_studio_server.studio  # the fixture: tv8 with S0..S2 locked


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
    assert studio.state.autosave_path.parent == autosave_dir()
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




def label_nodes(server) -> list[str]:
    """The label nodes a page opened now would receive."""
    return sorted(n for n in server.scene._handle_from_node_name
                  if n.startswith("/target_labels/"))


def test_load_of_fewer_poses_leaves_no_stale_labels(studio):
    """sun-path-fit (8 poses) then tv8 (4): the scene keeps four labels, for every page."""
    upload(studio, "sun-path-fit.json", (DESIGNS / "sun-path-fit.json").read_bytes())
    assert len(studio.scene.labels) == 8 and len(label_nodes(studio.server)) == 8
    upload(studio, "tv8.json", (DESIGNS / "tv8.json").read_bytes())
    assert label_nodes(studio.server) == [f"/target_labels/{i}" for i in range(4)]
    assert [lb.text.split()[0] for lb in studio.scene.labels] == ["S0", "S1", "S2", "S3"]
    assert sorted(n for n in studio.server.scene._handle_from_node_name
                  if n.startswith("/targets/") and n.count("/") == 2) == \
        [f"/targets/{i}" for i in range(4)]


def test_a_load_clears_older_error_notices(studio):
    studio.panels.locks[3].value = True  # refused: an error notice (all four locked)
    upload(studio, "broken.json", b"{")  # another error notice
    errors = {c for c, handles in studio.notices._shown.items() if c in studio.notices._errors}
    assert len(errors) == 2
    upload(studio, "tv8.json", (DESIGNS / "tv8.json").read_bytes())
    assert studio.notifications[-1][0] == "Design loaded"
    assert list(studio.notices._shown) == [LOAD] and not studio.notices._errors
    assert not studio.panels.busy.visible  # "working" is a line under the status, no toast


def test_autosave_is_written_during_a_realization_search(studio, monkeypatch):
    """A release whose quick search misses starts the full search; the released pose is on
    disk while that search still runs (it is held here until the autosave is seen), within
    2 s of the release."""
    monkeypatch.setattr(pipeline, "PREVIEW_WORK", 1)
    monkeypatch.setattr(solver_mod, "QUICK_WORK", 1)
    searching, release = threading.Event(), threading.Event()
    solve = studio.solver.solve

    def held_search(design, full, current, progress=None, *, check=None, **kw):
        if check is not None:  # the full search, a job on the worker
            searching.set()
            release.wait(20)
        return solve(design, full, current, progress, check=check, **kw)

    monkeypatch.setattr(studio.solver, "solve", held_search)
    path, p = studio.state.autosave_path, studio.state.design.poses[3].position + 0.3
    try:
        released = time.time()
        gizmo_async(studio, 3, p)
        assert searching.wait(20) and studio.jobs.busy == "realization search"
        end = released + 10.0
        while time.time() < end and not (path.exists() and np.allclose(
                design_mod.load_design(path).poses[3].position, p)):
            time.sleep(0.02)
        assert studio.jobs.busy == "realization search"  # still searching
        assert path.stat().st_mtime - released <= 2.0
        assert np.allclose(design_mod.load_design(path).poses[3].position, p)
    finally:
        release.set()
    settle(studio)


def gizmo_async(app, i: int, position) -> None:
    """A drag of gizmo ``i`` to ``position`` and its release, not waiting for the worker."""
    g = app.scene.gizmos[i]
    g.position = np.asarray(position, float)
    for phase in ("update", "end"):
        app._on_gizmo(i, viser.TransformControlsEvent(None, None, g, phase))


def test_autosaves_live_in_the_state_folder_and_old_ones_move_there(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    path = autosave_path_for(tmp_path / "a.json", "a")
    assert path.parent == autosave_dir() == tmp_path / "state" / "paraloop" / "autosave"
    old = legacy_autosave_dir() / path.name
    old.parent.mkdir(parents=True)
    design_mod.save_design(design_mod.load_design(DESIGN), old)
    os.utime(old, (1e9, 1e9))
    assert migrate_autosave(path) and path.exists() and not old.exists()
    assert path.stat().st_mtime == 1e9  # its time kept for the restore offer
    assert not migrate_autosave(path)  # nothing left to move
