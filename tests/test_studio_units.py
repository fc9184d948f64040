"""Unit tests of the studio's parts without a browser: state and history, the worker,
parsing, autosave locations and the command line."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
import pytest

from app import studio as studio_mod
from app.panels.realization import parse_fixed
from app.state import StudioState, autosave_path_for
from app.worker import FULL, PREVIEW, NewestWorker
from paraloop_core import design as design_mod

DESIGN = Path(__file__).resolve().parent.parent / "assets" / "designs" / "tv8.json"


def test_autosave_location(tmp_path, monkeypatch):
    """Never beside the design, in the user state folder; one file per opened path (two
    a.json never share one)."""
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    folder = tmp_path / "state" / "paraloop" / "autosave"
    one, two = autosave_path_for(tmp_path / "a.json", "x"), autosave_path_for(
        tmp_path / "sub" / "a.json", "x")
    assert one.parent == two.parent == folder and one != two
    assert one.name.startswith("a-") and one == autosave_path_for(tmp_path / "a.json", "y")
    assert autosave_path_for(None, "my design!") == folder / "my_design_.json"


def test_state_history():
    d = design_mod.load_design(DESIGN)
    st = StudioState(d)
    st.move_pose(3, np.ones(3), np.array([1.0, 0, 0, 0]), commit=False)
    assert not st.undo_stack
    st.commit()
    assert st.undo() and st.design is d and not st.undo()
    assert st.redo() and np.allclose(st.design.poses[3].position, 1.0)
    assert not st.move_pose(0, np.zeros(3), np.array([1.0, 0, 0, 0]), commit=True)  # locked
    assert not st.remove_pose(1)  # every design keeps at least four targets
    st.add_pose(st.design.poses[1])
    assert st.remove_pose(1) and st.design.locked == (0, 1)


def test_worker_merges_and_reports_slow_jobs():
    runs, events = [], []

    def job(level):
        runs.append(level)
        time.sleep(0.4 if level == FULL else 0.05)

    w = NewestWorker(job, on_slow=lambda: events.append("slow"),
                     on_slow_done=lambda: events.append("done"))
    try:
        w.request(PREVIEW)
        time.sleep(0.01)
        for _ in range(20):
            w.request(PREVIEW)
        w.request(FULL)
        assert w.wait_idle(5)
        assert runs == [PREVIEW, FULL] and events == ["slow", "done"]
    finally:
        w.close()


def test_parse_fixed():
    assert parse_fixed(" 0=0.1, 3=-2 ") == {0: 0.1, 3: -2.0}
    assert parse_fixed("") == {}
    for bad in ("7=1", "a=1", "1=x", "1"):
        with pytest.raises(ValueError):
            parse_fixed(bad)


def test_cli_serves_and_stops(tmp_path):
    import signal
    import subprocess
    import sys
    import urllib.request

    env = dict(os.environ, XDG_DATA_HOME=str(tmp_path))
    design = tmp_path / "tv8.json"
    design.write_bytes(DESIGN.read_bytes())
    proc = subprocess.Popen([sys.executable, "-m", "app.studio", str(design), "--port", "0"],
                            stdout=subprocess.PIPE, text=True, env=env,
                            cwd=Path(__file__).resolve().parent.parent)
    try:
        url = ""
        for line in proc.stdout:
            if line.startswith("open http://127.0.0.1:"):
                url = line.split()[1]
                break
        assert url, "no URL printed"
        assert b"<html" in urllib.request.urlopen(url, timeout=10).read().lower()
    finally:
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=20) == 0


def test_cli_register():
    import argparse

    parser = argparse.ArgumentParser()
    studio_mod.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["studio", "x.json", "--port", "0"])
    assert (args.design, args.host, args.port) == ("x.json", "127.0.0.1", 0)
    assert studio_mod.default_design_path().suffix == ".json"


def test_cli_reports_a_bad_file(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text("{")
    assert studio_mod.main([str(bad), "--port", "0"]) == 2
    assert capsys.readouterr().err.startswith("error: file: not valid JSON")


def test_fabrication_tasks_queue_once():
    st = StudioState(design_mod.load_design(DESIGN))
    st.add_task("carve", "a")
    st.add_task("export", "b")
    st.add_task("carve", "c")  # pressed again: runs once, for the last client
    assert st.take_tasks() == [("export", "b"), ("carve", "c")]
    assert st.take_tasks() == []
