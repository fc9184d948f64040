"""Headless studio tests of the End-effector panel: built-in bodies, mesh uploads (stored,
validated in the worker, refused with a notification) and removal."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
import viser

from app import studio as studio_mod
from app.panels import effector as effector_panel
from app.state import absolute_mesh
from paraloop_core import design as design_mod
from tests.test_studio_server import click, settle, upload

DESIGN = Path(__file__).resolve().parent.parent / "assets" / "designs" / "sun-disc.json"


@pytest.fixture
def studio(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = studio_mod.Studio(server, design_mod.load_design(DESIGN), tmp_path / "a.json")
    settle(app)
    yield app
    app.close()
    server.stop()


def bars(app) -> int:
    return len(app.scene.handles["bars"].batched_positions)


def box_stl(zero_area_face: bool = False) -> bytes:
    box = trimesh.creation.box((0.3, 0.2, 0.05))
    faces = box.faces
    if zero_area_face:
        faces = np.vstack([faces, [[0, 1, 1]]])
    return trimesh.Trimesh(box.vertices, faces, process=False).export(file_type="stl")


def test_builtin_disc_then_none(studio):
    assert studio.panels.effector.report.content == "*No end-effector.*" and bars(studio) == 6
    studio.panels.effector.body.value = "Disc"
    settle(studio)
    ee = studio.state.design.end_effector
    assert ee is not None and ee.shape == "disc" and ee.scale == 1.0 and ee.mesh is None
    assert studio.error is None and studio.solution.end_effector is not None
    assert "effector" in studio.scene.handles and bars(studio) == 7
    assert "all 29 pairs certified ✓" in studio.panels.effector.report.content
    studio.panels.effector.inputs["L"].value = "x"  # refused: notification, design kept
    settle(studio)
    assert studio.notifications[-1][2] and studio.state.design.end_effector == ee
    assert studio.panels.effector.inputs["L"].value == ""
    studio.panels.effector.body.value = "None"
    settle(studio)
    assert studio.state.design.end_effector is None and studio.solution.end_effector is None
    assert "effector" not in studio.scene.handles and bars(studio) == 6
    click(studio.panels.undo)
    settle(studio)
    assert studio.state.design.end_effector == ee and bars(studio) == 7
    assert studio.panels.effector.body.value == "Disc"


def test_mesh_upload_is_stored_validated_and_saved(studio, tmp_path, monkeypatch):
    panel = studio.panels.effector
    panel.body.value = "Mesh"  # nothing uploaded yet: refused
    settle(studio)
    assert studio.notifications[-1][2] and studio.state.design.end_effector is None
    assert panel.body.value == "None"
    upload(studio, "my box.stl", box_stl(), panel.upload)
    settle(studio)
    ee = studio.state.design.end_effector
    stored = Path(ee.mesh)
    assert stored.is_absolute() and stored.parent == tmp_path / "data" / "paraloop" / "meshes"
    assert stored.name.startswith("my-box-") and stored.suffix == ".stl"
    assert panel.body.value == "Mesh" and "12 faces" in panel.file.content
    assert studio.error is None and studio.solution.end_effector is not None
    assert "effector" in studio.scene.handles and bars(studio) == 7
    assert len(studio.scene.handles["effector"].faces) == 12
    click(studio.panels.save)  # the downloaded design names the upload, no server path
    saved = json.loads(studio.downloads[-1][1])
    assert saved["end_effector"]["mesh"] == stored.name
    upload(studio, "box.glb", trimesh.creation.box((0.2, 0.2, 0.1)).export(file_type="glb"),
           panel.upload)
    assert Path(studio.state.design.end_effector.mesh).suffix == ".glb" and bars(studio) == 7
    click(studio.panels.undo)  # each upload is one undoable edit
    settle(studio)
    assert studio.state.design.end_effector == ee
    good = studio.state.design
    monkeypatch.setattr(effector_panel, "MAX_UPLOAD_BYTES", 10**4)
    for name, data in (("junk.stl", b"\x00not a mesh at all"),
                       ("flat.stl", box_stl(zero_area_face=True)),
                       ("notes.txt", b"solid"), ("big.obj", b"#" * 20000)):
        upload(studio, name, data, panel.upload)
        settle(studio)
        title, body, error = studio.notifications[-1]
        assert error and "design is unchanged" in body, (name, body)
        assert studio.state.design is good and studio.solution.end_effector is not None
    assert "zero area" in studio.notifications[-3][1]
    kept = sorted(p.suffix for p in stored.parent.iterdir())  # the bad ones are deleted
    assert kept == [".glb", ".stl"]


def test_mesh_store_and_absolute_paths(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path))
    a = effector_panel.store_mesh("Panel v2.STL", b"one")
    assert a == tmp_path / "paraloop" / "meshes" / a.name and a.read_bytes() == b"one"
    assert a.name.startswith("Panel-v2-") and a.suffix == ".stl"
    assert effector_panel.store_mesh("Panel v2.STL", b"one") == a
    assert effector_panel.store_mesh("Panel v2.STL", b"two") != a
    design = design_mod.load_design(DESIGN.with_name("shading-panel.json"))
    portable = absolute_mesh(design)
    mesh = Path(portable.end_effector.mesh)
    assert mesh.is_absolute() and mesh == DESIGN.parent.parent / "meshes" / "shading-panel.stl"
    assert absolute_mesh(portable) is portable
