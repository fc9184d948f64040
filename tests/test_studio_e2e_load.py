"""End to end in real headless Chromium: *Load design* and the mesh-path rule (issue 28 item 4).
A design whose end-effector mesh points outside the opened design's folder is refused with one
message in the page and the design stays; one whose mesh lies inside the folder loads.

Skipped when chromium or playwright is missing, except under ``CI=true`` where that fails.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from paraloop_core import design as design_mod
from tests.browser_support import CHROMIUM, CHROMIUM_ARGS, playwright_sync, serve, wait_for

pytestmark = pytest.mark.browser

ASSETS = Path(__file__).resolve().parent.parent / "assets"
TV8 = json.loads((ASSETS / "designs" / "tv8.json").read_text())


def _design(path: Path, mesh: str) -> Path:
    path.write_text(json.dumps({**TV8, "name": path.stem,
                                "end_effector": {"mesh": mesh, "scale": 0.05}}))
    return path


def test_load_design_refuses_a_mesh_outside_the_design_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "data"))
    folder, outside = tmp_path / "designs", tmp_path / "outside"
    folder.mkdir()
    outside.mkdir()
    mesh = (ASSETS / "meshes" / "shading-panel.stl").read_bytes()
    (folder / "inside.stl").write_bytes(mesh)
    (outside / "secret.stl").write_bytes(mesh)
    (folder / "tv8.json").write_text(json.dumps(TV8))
    uploads = tmp_path / "uploads"
    uploads.mkdir()
    evil = _design(uploads / "evil.json", "../outside/secret.stl")
    good = _design(uploads / "good.json", "inside.stl")

    with serve(design_mod.load_design(folder / "tv8.json")) as studio, \
            playwright_sync.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(f"http://127.0.0.1:{studio.server.get_port()}/")
        page.wait_for_selector("canvas", timeout=60_000)
        page.get_by_text("Connected").first.wait_for(timeout=60_000)

        def load(path: Path) -> None:
            with page.expect_file_chooser(timeout=15_000) as chooser:
                page.get_by_role("button", name="Load design").click()
            chooser.value.set_files(str(path))

        before, start = studio.state.design, len(studio.notifications)
        load(evil)
        page.get_by_text("Cannot load evil.json").first.wait_for(timeout=30_000)
        assert page.get_by_text("end_effector.mesh", exact=False).first.is_visible()
        assert studio.worker.wait_idle(60)
        said = studio.notifications[start:]
        assert len(said) == 1 and said[0][2] and "end_effector.mesh" in said[0][1], said
        assert studio.state.design is before

        load(good)
        assert wait_for(lambda: studio.state.design.name == "good", 30), \
            studio.notifications[start:]
        assert studio.worker.wait_idle(60)
        page.get_by_text("Design loaded").first.wait_for(timeout=30_000)
        assert studio.error is None and studio.solution.end_effector is not None
        assert design_mod.mesh_file(studio.state.design) == str(folder / "inside.stl")
        assert not errors, errors
        browser.close()
