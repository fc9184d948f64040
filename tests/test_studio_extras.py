"""Headless studio tests of the end-effector drawing and the evolution controls."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import viser

from app import studio as studio_mod
from paraloop_core import design as design_mod
from paraloop_core.algebra import dq, poly
from paraloop_core.linkage import loops
from tests.test_studio_server import settle

ASSETS = Path(__file__).resolve().parent.parent / "assets" / "designs"


def _open(tmp_path, name: str):
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = studio_mod.Studio(server, design_mod.load_design(ASSETS / name),
                            tmp_path / "d.autosave.json")
    settle(app)
    return server, app


@pytest.fixture
def panel_studio(tmp_path):
    server, app = _open(tmp_path, "shading-panel.json")
    yield app
    app.close()
    server.stop()


def test_end_effector_moves_with_the_end_link(panel_studio):
    app = panel_studio
    sol = app.solution
    assert sol.end_effector is not None and app.error is None
    handle = app.scene.handles["effector"]
    assert len(app.scene.handles["bars"].batched_positions) == 7  # S3 L and R E3 replace S3 E3
    for u in (0.2, 0.7):
        app.panels.u.value = u
        settle(app)
        link3 = loops.link_poses(sol.loop.joint_factors, poly.param_to_t(np.array([u])))[0, 3]
        pos, wxyz = dq.to_pos_wxyz(link3)
        assert np.allclose(handle.position, pos, atol=1e-5)
        assert np.allclose(np.abs(np.dot(handle.wxyz, wxyz)), 1.0, atol=1e-5)


def test_evolution_controls_edit_the_design_and_report_the_fit(tmp_path):
    server, app = _open(tmp_path, "sun-path-fit.json")
    try:
        assert app.solution.fit is not None
        assert "Fit: cost" in app.panels.evolution.report.content
        app.panels.evolution.handles["starts"].value = 2
        settle(app)
        assert app.state.design.evolution["starts"] == 2
        assert app.solution.fit.starts_tried <= 2
        app.panels.evolution.handles["w0"].value = 0.5  # invalid (< 1): refused, design kept
        settle(app)
        assert "w0" not in app.state.design.evolution and app.notifications[-1][2]
        assert "w0" in app.notifications[-1][1]
        assert app.panels.evolution.handles["w0"].value == 3.0  # written back
        assert app.solution.fit is not None
    finally:
        app.close()
        server.stop()


def test_export_zip_builds_link_3_with_the_end_effector(panel_studio):
    import io
    import json
    import zipfile

    from app.exports import export_zip
    from app.state import FabSettings

    name, data, report = export_zip(panel_studio.solution, FabSettings(size_mm=500.0))
    assert report["verification"]["ok"] and report["end_effector"]["method"] == "closed"
    with zipfile.ZipFile(io.BytesIO(data)) as zf:
        names = zf.namelist()
        assert {"link_3.stl", "paraloop.3mf", "assembly.glb", "report.json"} <= set(names)
        assert json.loads(zf.read("report.json"))["verification"]["ok"]
