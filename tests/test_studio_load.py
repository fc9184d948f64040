"""*Load design* in the studio (issue 28 item 4), headless: the command line's loader with the
same limits and answers, every failure one notification with the design unchanged, and the
mesh-path rule (the design's folder, the bundled meshes by name, the uploaded meshes; never
elsewhere on the machine, and no answer to whether a file exists there)."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import pytest
import viser

from app import studio as studio_mod
from app.restore import newer_autosave
from app.state import StudioState, uploaded_meshes_dir
from paraloop_core import design as design_mod
from paraloop_core.design_checks import MAX_FILE_BYTES
from paraloop_core.errors import DesignFileError, shown
from tests.test_studio_server import settle, upload

ROOT = Path(__file__).resolve().parent.parent
ASSETS = ROOT / "assets"
TV8 = json.loads((ASSETS / "designs" / "tv8.json").read_text())
MESH = (ASSETS / "meshes" / "shading-panel.stl").read_bytes()


def _open(path: Path, autosave: Path | None = None):
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = studio_mod.Studio(server, design_mod.load_design(path), autosave)
    settle(app)
    return server, app


@pytest.fixture
def folder(tmp_path, monkeypatch):
    """A design folder ``designs/`` (tv8 and a mesh ``inside.stl``) beside ``outside/``
    holding ``secret.stl``; the user data folder in tmp_path."""
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    designs, outside = tmp_path / "designs", tmp_path / "outside"
    designs.mkdir()
    outside.mkdir()
    (designs / "tv8.json").write_text(json.dumps(TV8))
    (designs / "inside.stl").write_bytes(MESH)
    (outside / "secret.stl").write_bytes(MESH)
    return designs


@pytest.fixture
def studio(folder):
    server, app = _open(folder / "tv8.json")
    yield app
    app.close()
    server.stop()


def _with_mesh(mesh: str, scale: float = 0.05) -> bytes:
    return json.dumps({**TV8, "end_effector": {"mesh": mesh, "scale": scale}}).encode()


def _one_refusal(app, name: str, content: bytes) -> str:
    """Upload ``content``: exactly one new notification, an error naming the file, the design
    unchanged; its body."""
    before, start = app.state.design, len(app.notifications)
    upload(app, name, content)
    new = app.notifications[start:]
    assert len(new) == 1, new
    title, body, error = new[0]
    assert error and name in title and body.endswith("(the design is unchanged)"), new
    assert app.state.design is before
    return body.removesuffix(" (the design is unchanged)")


def test_every_bad_upload_is_one_message(studio):
    """The uploads that once failed silently in the handler, and the other limits."""
    good = json.dumps(TV8)
    cases = {
        "digits.json": (good.replace('"loop": 1', '"loop": ' + "7" * 5000), "file: number"),
        "w0.json": (json.dumps({**TV8, "evolution": {"w0": 10**400}}), "evolution.w0"),
        "deep.json": ("[" * 100_000, "file: nested deeper than 16"),
        "mesh.json": (_with_mesh("m" * 4096).decode(), "end_effector.mesh"),
        "nan.json": (json.dumps({**TV8, "loop": float("nan")}), "file: NaN"),
        "dup.json": ('{"name": "a", "name": "b"}', 'duplicate key "name"'),
        "latin1.json": (b'{"name": "\xe9"}', "not UTF-8"),
        "huge.json": (b"[" * (200 * 2**20), f"over the limit of {MAX_FILE_BYTES} bytes"),
    }
    for name, (content, words) in cases.items():
        raw = content if isinstance(content, bytes) else content.encode()
        body = _one_refusal(studio, name, raw)
        assert words in body and "\n" not in body and len(body) < 600, (name, body)


def test_studio_and_command_line_give_the_same_answer(studio, tmp_path):
    """One loader: the same bytes get the same refusal (or both load), BOM included."""
    good = (ASSETS / "designs" / "tv8.json").read_bytes()
    payloads = {"bom.json": b"\xef\xbb\xbf" + good,
                "dup.json": b'{"name": "a", "name": "b"}',
                "deep.json": b"[" * 1000,
                "int.json": good.replace(b'"loop": 1', b'"loop": ' + b"9" * 2000),
                "w0.json": json.dumps({**TV8, "evolution": {"w0": 10**400}}).encode(),
                "big.json": b" " * (MAX_FILE_BYTES + 1)}
    for name, raw in payloads.items():
        path = tmp_path / name
        path.write_bytes(raw)
        try:
            design_mod.load_design(path)
            cli = None
        except DesignFileError as exc:
            cli = str(exc)
        if cli is None:
            upload(studio, name, raw)
            assert studio.notifications[-1][0] == "Design loaded", name
        else:
            assert _one_refusal(studio, name, raw) == cli, name


def test_mesh_paths_only_inside_the_allowed_folders(studio, folder):
    """Absolute paths and paths leaving the design's folder are refused with one message that
    is the same whether the file exists; a mesh inside the folder, a bundled one by name and
    an uploaded one by name load."""
    secret = folder.parent / "outside" / "secret.stl"
    said = {}
    for mesh in (str(secret), str(secret.with_name("none.stl")), "../outside/secret.stl",
                 "../outside/none.stl", "sub/../../outside/secret.stl"):
        said[mesh] = _one_refusal(studio, "evil.json", _with_mesh(mesh))
        assert said[mesh].startswith("end_effector.mesh: ")
    assert len({body.replace(shown(m), "<m>") for m, body in said.items()}) == 1, said
    upload(studio, "inside.json", _with_mesh("inside.stl"))
    settle(studio)
    assert studio.notifications[-1][0] == "Design loaded"
    assert studio.solution.end_effector is not None and studio.error is None
    upload(studio, "bundled.json", _with_mesh("../meshes/shading-panel.stl"))
    assert studio.notifications[-1][0] == "Design loaded"
    assert design_mod.mesh_file(studio.state.design) == str(ASSETS / "meshes" /
                                                            "shading-panel.stl")
    stored = studio.panels.effector  # an uploaded mesh is found again by its file name
    upload(studio, "box.stl", MESH, stored.upload)
    name = Path(studio.state.design.end_effector.mesh).name
    assert Path(studio.state.design.end_effector.mesh).parent == uploaded_meshes_dir()
    upload(studio, "uploaded.json", _with_mesh(name))
    assert studio.notifications[-1][0] == "Design loaded"
    assert design_mod.mesh_file(studio.state.design) == str(uploaded_meshes_dir() / name)


def test_a_copy_of_the_designs_folder_opens_shading_panel_with_its_mesh(tmp_path):
    copy = tmp_path / "designs"
    shutil.copytree(ASSETS / "designs", copy)
    design = design_mod.load_design(copy / "shading-panel.json")
    assert design.end_effector.mesh == "../meshes/shading-panel.stl"  # as written
    assert design_mod.mesh_file(design) == str(ASSETS / "meshes" / "shading-panel.stl")
    server, app = _open(copy / "shading-panel.json")
    try:
        assert app.error is None and app.solution.end_effector is not None
        assert not [n for n in app.notifications if n[2]], app.notifications
    finally:
        app.close()
        server.stop()


def test_restored_autosave_keeps_no_broken_mesh_path(folder, tmp_path):
    """An autosave is loaded as the opened design: its mesh path resolves in the design's
    folder (or by name among the bundled and uploaded meshes), or the autosave is refused;
    a broken absolute path of an older version is found again by its name."""
    opened = folder / "tv8.json"
    autosave = tmp_path / "autosave.json"
    for mesh, found in (("inside.stl", folder / "inside.stl"),
                        ("/gone/../meshes/shading-panel.stl",
                         ASSETS / "meshes" / "shading-panel.stl")):
        autosave.write_bytes(_with_mesh(mesh))
        design, _ = newer_autosave(autosave, None, str(folder))
        assert design_mod.mesh_file(design) == str(found)
    autosave.write_bytes(_with_mesh("/etc/hosts"))
    said = newer_autosave(autosave, None, str(folder))
    assert isinstance(said, str) and "end_effector.mesh" in said
    # what the studio writes for an uploaded mesh is its name: no server path
    state = StudioState(design_mod.load_design(opened), autosave)
    stored = uploaded_meshes_dir() / "box-0123456789ab.stl"
    stored.parent.mkdir(parents=True)
    stored.write_bytes(MESH)
    ee = design_mod.EndEffectorSettings(mesh=str(stored), scale=0.05)
    state.commit(dataclasses.replace(state.design, end_effector=ee))
    assert state.autosave()
    assert json.loads(autosave.read_text())["end_effector"]["mesh"] == stored.name
    design, _ = newer_autosave(autosave, None, str(folder))
    assert design_mod.mesh_file(design) == str(stored)
