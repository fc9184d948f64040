"""End-to-end tests of the studio in real headless Chromium (Debian package) via Playwright.

Skipped when chromium or playwright is missing, except under ``CI=true`` where that fails.
Never run ``playwright install``. ``PARALOOP_SCREENSHOT=docs/studio.png`` saves the first
screenshot (how ``docs/studio.png`` is made).
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from viser import transforms as tf

from app.worker import FULL
from paraloop_core import design as design_mod
from tests.browser_support import CHROMIUM, CHROMIUM_ARGS, playwright_sync, serve, wait_for

pytestmark = pytest.mark.browser

DESIGN = Path(__file__).resolve().parent.parent / "assets" / "designs" / "tv8.json"


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    design = dataclasses.replace(design_mod.load_design(DESIGN), locked=(0, 1, 2))
    with serve(design, tmp_path_factory.mktemp("autosave") / "tv8.autosave.json") as studio:
        yield studio


@pytest.fixture(scope="module")
def page(app):
    udd = tempfile.mkdtemp(prefix="chromium-udd-")
    errors: list[str] = []
    with playwright_sync.sync_playwright() as p:
        ctx = p.chromium.launch_persistent_context(
            udd, executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True,
            viewport={"width": 1280, "height": 800}, accept_downloads=True)
        pg = ctx.pages[0] if ctx.pages else ctx.new_page()
        pg.on("pageerror", lambda e: errors.append(str(e)))
        pg.goto(f"http://127.0.0.1:{app.server.get_port()}/")
        pg.wait_for_selector("canvas", timeout=30_000)
        assert wait_for(lambda: len(app.server.get_clients()) == 1), "browser never connected"
        client = next(iter(app.server.get_clients().values()))
        assert wait_for(lambda: client.camera.update_timestamp != 0.0), "no camera report"
        time.sleep(1.5)  # first frames
        pg.js_errors = errors  # type: ignore[attr-defined]
        pg.viser_client = client  # type: ignore[attr-defined]
        yield pg
        ctx.close()
    shutil.rmtree(udd, ignore_errors=True)


def shot(page, path: Path) -> np.ndarray:
    page.screenshot(path=str(path))
    return np.asarray(Image.open(path).convert("RGB")).astype(int)


def changed_pixels(a: np.ndarray, b: np.ndarray) -> int:
    return int((np.abs(a - b).sum(-1) > 60).sum())


def test_scene_renders_linkage(app, page, tmp_path):
    for button in page.locator("[class*=Notification-closeButton]").all():  # software-GL notice
        button.click()
    cam = page.viser_client.camera
    view = cam.position.copy(), cam.look_at.copy()
    if os.environ.get("PARALOOP_SCREENSHOT"):  # a closer view for the docs
        pts = np.concatenate([app.scene.points_home, app.state.design.pose_array[0]])
        size = np.linalg.norm(pts.max(0) - pts.min(0))
        cam.look_at = pts.mean(0) + np.array([0.15, 0.0, 0.0]) * size
        cam.position = pts.mean(0) + np.array([0.5, -0.7, 0.4]) * size
        app.panels.thickness.value = 3.0  # true-radius bars are thin at this zoom
    assert app.worker.wait_idle(30)
    time.sleep(1.0)
    img = shot(page, tmp_path / "on.png")
    if os.environ.get("PARALOOP_SCREENSHOT"):
        shutil.copy(tmp_path / "on.png", os.environ["PARALOOP_SCREENSHOT"])
        app.panels.thickness.value = 1.0
        cam.position, cam.look_at = view
    app.panels.layers["Linkage"].value = False
    assert app.worker.wait_idle(30) and not app.scene.handles["bars"].visible
    time.sleep(1.0)
    off = shot(page, tmp_path / "off.png")
    app.panels.layers["Linkage"].value = True
    assert app.worker.wait_idle(30) and app.scene.handles["bars"].visible
    time.sleep(0.5)
    assert changed_pixels(img, off) > 300, "the linkage is not visible"
    assert page.get_by_text("Connected").first.is_visible()
    assert "Collision-free loop found" in app.panels.status.content
    assert not page.js_errors, page.js_errors


def projector(page):
    """World -> CSS pixels from the client's camera (OpenCV convention, vertical fov)."""
    cam = page.viser_client.camera
    rot, c = tf.SO3(cam.wxyz).as_matrix(), cam.position.copy()
    bb = page.locator("canvas").first.bounding_box()
    f = (bb["height"] / 2) / np.tan(cam.fov / 2)

    def proj(pw):
        pc = rot.T @ (np.asarray(pw, dtype=float) - c)
        return np.array([bb["x"] + bb["width"] / 2 + f * pc[0] / pc[2],
                         bb["y"] + bb["height"] / 2 + f * pc[1] / pc[2]])

    return proj


def test_gizmo_drag_changes_motion(app, page):
    g = app.scene.gizmos[3]
    proj = projector(page)
    c, rg, s = g.position.copy(), tf.SO3(g.wxyz).as_matrix(), g.scale
    lens = [np.linalg.norm(proj(c + s * rg[:, a]) - proj(c)) for a in range(3)]
    a = int(np.argmax(lens))
    d = proj(c + s * rg[:, a]) - proj(c)
    d /= np.linalg.norm(d)
    start = proj(c + 0.9 * s * rg[:, a])
    path0 = app.scene.handles["path"].points.copy()
    undo = len(app.state.undo_stack)
    page.mouse.move(*start)
    page.mouse.down()
    for k in range(1, 11):
        page.mouse.move(*(start + 50 * d * k / 10))
        time.sleep(0.03)
    page.mouse.up()
    assert wait_for(lambda: len(app.state.undo_stack) == undo + 1, 5), "drag never committed"
    assert app.worker.wait_idle(30)
    moved = app.state.design.poses[3].position - c
    assert moved @ rg[:, a] > 0.02, moved
    assert app.solution.design.poses[3] is app.state.design.poses[3]
    assert not np.allclose(app.scene.handles["path"].points, path0, atol=1e-4)


def test_slider_moves_linkage(app, page, tmp_path):
    before = shot(page, tmp_path / "a.png")
    bars = app.scene.handles["bars"].batched_positions.copy()
    box = page.locator(f'[id="{app.panels.u._impl.uuid}"]').locator("xpath=..") \
        .locator("input[inputmode=decimal]")
    box.fill("0.3")
    box.press("Enter")
    assert wait_for(lambda: abs(app.state.u - 0.3) < 1e-9)
    assert app.worker.wait_idle(30)
    assert not np.allclose(app.scene.handles["bars"].batched_positions, bars, atol=1e-4)
    time.sleep(1.0)
    assert changed_pixels(before, shot(page, tmp_path / "b.png")) > 300


def test_loop_picker_switches_loop(app, page):
    page.get_by_role("combobox", name="Loop variant").click()
    page.get_by_role("option", name="loop 4 ·").click()
    assert wait_for(lambda: app.state.design.loop == 4)
    assert app.worker.wait_idle(30)
    assert app.solution.design.loop == 4


def test_save_and_export_download(app, page):
    with page.expect_download(timeout=30_000) as dl:
        page.get_by_role("button", name="Save design").click()
    saved = design_mod.load_design(dl.value.path())
    assert np.allclose(saved.pose_array[0], app.state.design.pose_array[0])
    with page.expect_download(timeout=30_000) as dl:
        page.get_by_role("button", name="Export result").click()
    assert dl.value.suggested_filename == "paraloop-result.json"
    result = json.loads(Path(dl.value.path()).read_text())
    assert result["format"] == "paraloop-result" and result["loop"] == app.state.design.loop


def test_broken_upload_shows_error_and_keeps_design(app, page, tmp_path):
    bad = tmp_path / "broken.json"
    bad.write_text('{"format": "paraloop-design", "poses": "none"}')
    before = app.state.design
    with page.expect_file_chooser() as fc:
        page.get_by_role("button", name="Load design").click()
    fc.value.set_files(str(bad))
    page.get_by_text("Cannot load broken.json").first.wait_for(timeout=10_000)
    assert app.state.design is before
    assert app.solution is not None and app.error is None


def test_fabrication_export_zip_download(app, page):
    # back to the example (earlier tests moved S3 and picked a loop whose motion is too close
    # to a singular pose to bound its speed, which the export refuses with a notification)
    app.state.commit(design_mod.load_design(DESIGN))
    app.request(FULL, sync=True)
    assert app.worker.wait_idle(30) and app.solution.realization is not None
    page.get_by_text("Fabrication", exact=True).click()  # the folder starts collapsed
    button = page.get_by_role("button", name="Export all (zip)")
    button.wait_for(timeout=10_000)
    try:
        with page.expect_download(timeout=300_000) as dl:  # a loaded machine: ~20 s alone
            before = app.fabrication.progress_text.content
            button.click()
            # a click lost on a loaded machine (no job, no progress within 20 s) is repeated:
            # the subject here is the download and its contents
            if not wait_for(lambda: app.jobs.busy is not None
                            or app.fabrication.progress_text.content != before, 20):
                button.click()
    except playwright_sync.TimeoutError:
        pytest.fail(f"no download; job running: {app.jobs.busy}, progress: "
                    f"{app.fabrication.progress_text.content!r}, last notifications: "
                    f"{app.notifications[-3:]}")
    assert dl.value.suggested_filename.startswith("paraloop-")
    with zipfile.ZipFile(dl.value.path()) as zf:
        names = set(zf.namelist())
        report = json.loads(zf.read("report.json"))
    assert {"paraloop-result.json", "link_0.stl", "paraloop.3mf", "assembly.glb"} <= names
    assert report["verification"]["ok"]
    page.get_by_text("Verification: ok").first.wait_for(timeout=10_000)
