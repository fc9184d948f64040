"""End-to-end tests of the studio's workflow in real headless Chromium (Debian package).

Framing of every bundled example (opened from a read-only copy), autosave and restore after a
crash of a real ``python -m app.studio`` process, save / load / undo through the buttons,
cancelling a long job, and four browsers on one studio.

Skipped when chromium or playwright is missing, except under ``CI=true`` where that fails.
Never run ``playwright install``.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import viser
from PIL import Image

from app import studio as studio_mod
from app.labels import overlaps
from paraloop_core import design as design_mod
from tests import browser_support
from tests.browser_support import (
    ASSETS,
    EXAMPLES,
    ROOT,
    TV8,
    click,
    connect,
    errors,
    extent,
    free_port,
    inside_fraction,
    label_boxes,
    new_page,
    number_box,
    open_studio,
    playwright_sync,
    save_design,
    serve,
    shifted,
    text_field,
    tree_state,
    upload,
    wait_for,
    wait_framed,
)
from tests.test_studio_plain import sentence_problems

pytestmark = pytest.mark.browser
browser = browser_support.browser  # the fixtures
readonly_assets = browser_support.readonly_assets

RESTORE = re.compile(r"^Restore changes from \d{1,2}:\d{2}")


def labels_apart(page, log, since: float, n: int) -> bool:
    """Whether the page's ``n`` pose labels, seen by its last camera reported after
    ``since``, have boxes that do not overlap (waits a little for the placed labels)."""
    def apart() -> bool:
        labels, report = page.scene.labels(), log.since(since)
        if len(labels) != n or report is None or any("position" not in v
                                                     for v in labels.values()):
            return False
        b = label_boxes(page, report, labels)
        return not (overlaps(b, b) & ~np.eye(n, dtype=bool)).any()

    return wait_for(apart, 10, 0.2)


# --- 1. framing of the bundled examples ---------------------------------------------------------
@pytest.mark.parametrize("example", EXAMPLES)
def test_open_and_frame_all_show_the_whole_design(example, readonly_assets, browser):
    """Each example opened from a read-only folder loads without errors and is framed left of
    the GUI panel on open (the object and the free targets) and by "Frame all" (everything)
    after the camera was moved away; the
    folder stays untouched. The page shows one plain status sentence, the linkage without
    the construction aids, and pose labels that do not overlap in its own camera (on open
    and after "Frame all")."""
    before = tree_state(readonly_assets)
    server, studio = open_studio(readonly_assets / "designs" / example)
    page = None
    try:
        assert studio.worker.wait_idle(60)
        page, client, log = connect(server, browser)
        assert studio.worker.wait_idle(60)
        assert not errors(studio), studio.notifications
        assert studio.status.sizes.wait_idle(30)
        sentence = studio.panels.status.content.strip("*")
        assert not sentence_problems(sentence), sentence
        assert wait_for(lambda: sentence in page.inner_text("body"), 45, 0.5), \
            [t for t in page.inner_text("body").splitlines() if "loop" in t]  # as shown
        shown = {k: v["visible"] for k, v in page.scene.nodes.items()}
        assert shown["/loop/bars"] and shown["/loop/joints"], shown
        assert not any(shown[k] for k in ("/factorizations", "/loop/axes", "/motion/frames",
                                          "/motion/current/ellipsoid")), shown
        pts = extent(studio, opening=True)  # the object and the free targets
        frac = wait_framed(page, log, pts, 0.0)
        assert frac >= 0.95, f"on open only {frac:.0%} of the object is left of the panel"
        pts = extent(studio)  # Frame all: every target, the trajectory and the object
        assert labels_apart(page, log, 0.0, len(studio.state.design.poses))

        center, size = pts.mean(0), max(np.ptp(pts, axis=0).max(), 1e-3)
        away = np.array([1.0, 1.0, 1.0]) / np.sqrt(3.0)
        t = time.time()
        client.camera.position = center + 40.0 * size * away
        client.camera.look_at = center + 41.0 * size * away  # looking away from the design
        assert wait_for(lambda: (r := log.since(t)) is not None
                        and inside_fraction(page, r, pts) < 0.5, 15, 0.2), \
            "the browser never showed the moved camera"
        t = time.time()
        click(page, "Frame all", "missing feature: top-level 'Frame all' button")
        frac = wait_framed(page, log, pts, t)
        assert frac >= 0.95, f"after 'Frame all' only {frac:.0%} is left of the panel"
        assert labels_apart(page, log, t, len(studio.state.design.poses))
        assert not errors(studio), studio.notifications
        assert not page.js_errors, page.js_errors
    finally:
        if page is not None:
            page.context.close()
        studio.close()
        server.stop()
    assert tree_state(readonly_assets) == before, "the studio wrote into the design folder"


# --- 5. four browsers ---------------------------------------------------------------------------
SMALL = {"width": 640, "height": 400}  # four software-rendered pages at 1280x800 crawl


def rendered_pixels(page, tmp_path: Path, tag: str) -> int:
    """Non-white pixels of the 3D view (below the notification, left of the panel)."""
    path = tmp_path / f"{tag}.png"
    page.screenshot(path=str(path))
    img = np.asarray(Image.open(path).convert("RGB")).astype(int)[160:390, 20:300]
    return int((img.min(-1) < 200).sum())


def test_four_browsers_share_one_studio(browser, tmp_path):
    """Four browsers on one studio are all connected and rendered without page errors, and a
    loop picked in one shows in the other three."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    studio = studio_mod.Studio(server, design_mod.load_design(TV8), tmp_path / "auto.json")
    pages = []
    try:
        assert studio.worker.wait_idle(60)
        for _ in range(4):
            pages.append(connect(server, browser, SMALL)[0])
        assert wait_for(lambda: len(server.get_clients()) == 4, 30), server.get_clients()
        assert studio.worker.wait_idle(60)
        for k, pg in enumerate(pages):
            assert wait_for(lambda pg=pg, k=k: rendered_pixels(pg, tmp_path, f"p{k}") > 1000,
                            20, 0.5), f"page {k} shows no scene"
        assert studio.state.design.loop != 4
        pages[0].get_by_role("combobox", name="Loop variant").click()
        option = pages[0].get_by_role("option", name=re.compile(r"^loop 4\b"))
        try:
            option.wait_for(state="visible", timeout=10_000)
        except playwright_sync.TimeoutError:
            pytest.fail("missing feature: no loop option labelled 'loop 4 ...'")
        option.click()
        assert wait_for(lambda: studio.state.design.loop == 4, 15)
        assert studio.worker.wait_idle(60)
        for pg in pages[1:]:
            playwright_sync.expect(pg.get_by_role("combobox", name="Loop variant")).to_have_value(
                re.compile(r"^loop 4\b"), timeout=15_000)
        assert len(server.get_clients()) == 4
        for k, pg in enumerate(pages):
            assert not pg.js_errors, (k, pg.js_errors)
    finally:
        for pg in pages:
            pg.context.close()
        studio.close()
        server.stop()


# --- 2. autosave and restore after a crash ------------------------------------------------------
def start_process(design: Path, port: int, xdg: Path, log: Path) -> subprocess.Popen:
    env = {**os.environ, "XDG_DATA_HOME": str(xdg), "XDG_STATE_HOME": str(xdg / "state"),
           "PYTHONUNBUFFERED": "1"}
    with log.open("ab") as out:
        proc = subprocess.Popen([sys.executable, "-m", "app.studio", str(design),
                                 "--port", str(port)], cwd=ROOT, env=env, stdout=out,
                                stderr=subprocess.STDOUT)
    ok = wait_for(lambda: f":{port}/" in log.read_text() or proc.poll() is not None, 90, 0.2)
    if not ok or proc.poll() is not None:
        proc.kill()
        pytest.fail(f"the studio did not start:\n{log.read_text()[-3000:]}")
    return proc


def stop_process(proc) -> None:
    if proc is not None and proc.poll() is None:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)


def test_autosave_survives_a_kill_and_restores_on_request(browser, tmp_path):
    """A name typed in the studio is autosaved within 2 s; after ``kill -9`` the restarted
    studio offers "Restore changes from HH:MM" / "Discard changes" instead of applying it,
    Restore brings the edit back (via "Save design"), and Undo returns to the file."""
    design = tmp_path / "designs" / "tv8.json"
    design.parent.mkdir()
    shutil.copy(TV8, design)
    original = design_mod.load_design(design).name
    xdg, log = tmp_path / "xdg", tmp_path / "studio.log"
    procs, pages = [None, None], []
    try:
        port = free_port()
        procs[0] = start_process(design, port, xdg, log)
        pages.append(new_page(browser, f"http://127.0.0.1:{port}/"))
        name = text_field(pages[0], "Name")
        playwright_sync.expect(name).to_have_value(original, timeout=30_000)
        name.fill("E2E autosaved name")
        name.press("Enter")
        time.sleep(2.5)
        autosaves = list((xdg / "state" / "paraloop" / "autosave").glob("tv8-*.json"))
        assert len(autosaves) == 1, (autosaves, log.read_text()[-2000:])
        assert design_mod.load_design(autosaves[0]).name == "E2E autosaved name"
        stop_process(procs[0])
        pages[0].context.close()

        port = free_port()
        procs[1] = start_process(design, port, xdg, log)
        pages.append(new_page(browser, f"http://127.0.0.1:{port}/"))
        pg = pages[1]
        restore = pg.get_by_role("button", name=RESTORE)
        try:
            restore.wait_for(state="visible", timeout=20_000)
        except playwright_sync.TimeoutError:
            pytest.fail("missing feature: no 'Restore changes from HH:MM' button after restart")
        assert pg.get_by_role("button", name="Discard changes").is_visible()
        name = text_field(pg, "Name")
        playwright_sync.expect(name).to_have_value(original, timeout=10_000)  # not silently
        restore.click()
        playwright_sync.expect(name).to_have_value("E2E autosaved name", timeout=30_000)
        assert save_design(pg)["name"] == "E2E autosaved name"
        click(pg, "Undo", "Undo button")
        playwright_sync.expect(name).to_have_value(original, timeout=30_000)
        assert not pg.js_errors, pg.js_errors
    finally:
        for pg in pages:
            try:
                pg.context.close()
            except playwright_sync.Error:
                pass
        for proc in procs:
            stop_process(proc)


# --- one in-process studio for save/load/undo and cancel ---------------------------------------
@pytest.fixture(scope="module")
def app(tmp_path_factory):
    with serve(design_mod.load_design(TV8),
               tmp_path_factory.mktemp("autosave") / "tv8.autosave.json") as studio:
        yield studio


@pytest.fixture(scope="module")
def page(app, browser):
    pg, _, log = connect(app.server, browser)
    pg.camera_log = log  # type: ignore[attr-defined]
    yield pg
    pg.context.close()


def test_save_load_undo_through_buttons(app, page, tmp_path):
    """"Save design" downloads the design, "Load design" of a modified copy replaces it (one
    "Design loaded", no error, status ok) and "Undo" brings the saved design back."""
    assert app.worker.wait_idle(60)
    saved = save_design(page)
    assert saved["name"] == app.state.design.name
    assert np.allclose([p["position"] for p in saved["poses"]], app.state.design.pose_array[0])

    modified = tmp_path / "modified.json"
    modified.write_text(json.dumps(shifted(saved, [0.25, 0.0, 0.0], "E2E loaded design")))
    start = len(app.notifications)
    upload(page, modified)
    assert wait_for(lambda: app.state.design.name == "E2E loaded design", 20), \
        app.notifications[start:]
    assert app.worker.wait_idle(60)
    assert [n[0] for n in app.notifications[start:]].count("Design loaded") == 1, \
        app.notifications[start:]
    assert not errors(app, start), app.notifications[start:]
    status = app.panels.status.content
    assert "Collision-free loop found" in status, status
    assert save_design(page)["name"] == "E2E loaded design"

    click(page, "Undo", "Undo button")
    assert wait_for(lambda: app.state.design.name == saved["name"], 20)
    assert app.worker.wait_idle(60)
    back = save_design(page)
    assert back["name"] == saved["name"]
    assert np.allclose([p["position"] for p in back["poses"]],
                       [p["position"] for p in saved["poses"]])
    assert not page.js_errors, page.js_errors


def test_load_design_frames_the_loaded_design(app, page, tmp_path):
    """After "Load design" of a design far from the current one, the camera shows it (>= 95 %
    of the object and free targets left of the panel); Undo restores the previous design."""
    assert app.worker.wait_idle(60)
    data = json.loads((ASSETS / "designs" / "sun-disc.json").read_text())
    far = tmp_path / "far.json"
    scale = np.ptp(np.array([p["position"] for p in data["poses"]]), axis=0).max()
    far.write_text(json.dumps(shifted(data, [30.0 * scale, -20.0 * scale, 5.0 * scale],
                                      "E2E far away")))
    start = len(app.notifications)
    t = time.time()
    upload(page, far)
    try:
        assert wait_for(lambda: app.state.design.name == "E2E far away", 20)
        assert app.worker.wait_idle(60)
        assert not errors(app, start), app.notifications[start:]
        pts = extent(app, opening=True)
        frac = wait_framed(page, page.camera_log, pts, t)
        assert frac >= 0.95, f"after 'Load design' only {frac:.0%} is left of the panel"
    finally:
        if app.state.design.name == "E2E far away":
            app.state.undo()
            app.request(studio_mod.FULL, sync=True)
            assert app.worker.wait_idle(60)


# --- 4. cancelling a long job -------------------------------------------------------------------
def job_busy(app) -> bool:
    """Whether the worker or a background job (``app.jobs`` if the studio has one) runs."""
    jobs = getattr(app, "jobs", None)
    return not app.worker.wait_idle(0.0) or bool(jobs is not None and jobs.busy)


def test_cancel_long_carve(app, page):
    """A carve at the largest voxel resolution shows "Cancel job"; clicking it stops the job
    within a few seconds with a "cancelled" message, and the studio still animates."""
    fab = app.fabrication
    assert app.worker.wait_idle(60)
    carve = page.get_by_role("button", name="Carve design spaces")
    if not carve.is_visible():
        page.get_by_text("Fabrication", exact=True).click()  # the folder starts collapsed
    carve.wait_for(state="visible", timeout=10_000)
    slider, resolution = fab.inputs["resolution"], app.state.fab.resolution
    box = number_box(page, slider)
    box.fill(str(int(slider.max)))
    box.press("Enter")
    assert wait_for(lambda: app.state.fab.resolution == int(slider.max), 10), app.state.fab
    start, carving, version = len(app.notifications), fab.carving, app.state.version
    carve.click()
    try:
        cancel = page.get_by_role("button", name="Cancel job")
        try:
            cancel.wait_for(state="visible", timeout=15_000)
        except playwright_sync.TimeoutError:
            pytest.fail("missing feature: no visible 'Cancel job' button while carving")
        time.sleep(1.0)
        assert job_busy(app) and cancel.is_visible(), "the carve was not a long job"
        t = time.monotonic()
        cancel.click()
        assert wait_for(lambda: not job_busy(app), 30), "the job did not stop"
        took = time.monotonic() - t
        assert took < 8.0, f"the job stopped {took:.1f} s after 'Cancel job'"
        playwright_sync.expect(cancel).to_be_hidden(timeout=10_000)
        assert fab.carving is carving, "the carve ran to its end"
        said = [f"{a} {b}" for a, b, _ in app.notifications[start:]] + \
            [app.panels.status.content, fab.progress_text.content]
        assert any("cancelled" in s.lower() for s in said), said
        assert not errors(app, start), app.notifications[start:]
        assert app.state.version == version, "cancelling changed the design"
    finally:
        if job_busy(app):  # no working cancel: stop it by a design "edit"
            app.state.preview(app.state.design)
            wait_for(lambda: not job_busy(app), 120, 0.2)
        app.state.fab = dataclasses.replace(app.state.fab, resolution=resolution)
        app.request(studio_mod.FRAME, sync=True)
        app.worker.wait_idle(60)
    bars = app.scene.handles["bars"].batched_positions.copy()
    u = 0.37 if abs(app.state.u - 0.37) > 0.05 else 0.71
    box = number_box(page, app.panels.u)
    box.fill(str(u))
    box.press("Enter")
    assert wait_for(lambda: abs(app.state.u - u) < 1e-9, 10), "the u slider is not served"
    assert app.worker.wait_idle(30)
    assert not np.allclose(app.scene.handles["bars"].batched_positions, bars, atol=1e-4)
    assert not page.js_errors, page.js_errors
