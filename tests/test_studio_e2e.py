"""End-to-end tests of the studio's workflow in real headless Chromium (Debian package).

Framing of every bundled example (opened from a read-only copy), autosave and restore after a
crash of a real ``python -m app.studio`` process, save / load / undo through the buttons,
cancelling a long job, and four browsers on one studio.

Skipped when chromium or playwright is missing, except under ``CI=true`` where that fails.
Never run ``playwright install``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import viser
from PIL import Image
from viser import transforms as tf

from app import studio as studio_mod
from app.state import autosave_path_for
from paraloop_core import design as design_mod
from tests.browser_support import CHROMIUM, CHROMIUM_ARGS, playwright_sync, serve, wait_for

pytestmark = pytest.mark.browser

ROOT = Path(__file__).resolve().parent.parent
ASSETS = ROOT / "assets"
EXAMPLES = sorted(p.name for p in (ASSETS / "designs").glob("*.json"))
TV8 = ASSETS / "designs" / "tv8.json"
VIEWPORT = {"width": 1280, "height": 800}
PANEL_WIDTH = 320  # viser's control panel, when its element cannot be found
RESTORE = re.compile(r"^Restore changes from \d{1,2}:\d{2}")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def tree_state(folder: Path) -> dict:
    """Every path under ``folder`` with its size, mtime and content hash."""
    out = {}
    for p in sorted(folder.rglob("*")):
        st = p.stat()
        digest = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
        out[str(p.relative_to(folder))] = (st.st_size, st.st_mtime_ns, digest)
    return out


def set_writable(folder: Path, writable: bool) -> None:
    paths = [folder, *folder.rglob("*")]
    for p in (reversed(paths) if not writable else paths):
        mode = 0o755 if p.is_dir() else 0o644
        p.chmod(mode if writable else mode & ~0o222)


# --- browser helpers ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def browser():
    with playwright_sync.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)
        yield b
        b.close()


def new_page(browser, url: str, viewport=None):
    """A page in its own context at ``url`` (1280x800, downloads on); ``page.js_errors``."""
    ctx = browser.new_context(viewport=viewport or VIEWPORT, accept_downloads=True)
    page = ctx.new_page()
    page.js_errors = []  # type: ignore[attr-defined]
    page.on("pageerror", lambda e: page.js_errors.append(str(e)))
    page.goto(url)
    page.wait_for_selector("canvas", timeout=60_000)
    page.get_by_text("Connected").first.wait_for(timeout=60_000)
    return page


def connect(server, browser, viewport=None):
    """Open a page on ``server``; returns (page, its viser client, its camera log)."""
    logs = camera_logs(server)
    known = set(server.get_clients())
    page = new_page(browser, f"http://127.0.0.1:{server.get_port()}/", viewport)
    assert wait_for(lambda: set(server.get_clients()) - known, 30), "browser never connected"
    cid = next(iter(set(server.get_clients()) - known))
    assert wait_for(lambda: cid in logs, 10)
    return page, server.get_clients()[cid], logs[cid]


class CameraLog:
    """The cameras a browser reported (time, position, wxyz, fov), newest last."""

    def __init__(self) -> None:
        self.reports: list[tuple[float, np.ndarray, np.ndarray, float]] = []

    def add(self, cam) -> None:
        s = cam._state  # replaced as a whole by each report of the browser
        self.reports.append((time.time(), s.position.copy(), s.wxyz.copy(), float(s.fov)))

    def since(self, t: float):
        return next((r for r in reversed(self.reports) if r[0] >= t), None)


def camera_logs(server) -> dict:
    """client id -> :class:`CameraLog` of every browser connecting to ``server`` from now on
    (registered before the page opens, so no report after the first one is missed)."""
    if not hasattr(server, "e2e_camera_logs"):
        server.e2e_camera_logs = {}

        def on_connect(client):
            log = CameraLog()
            log.add(client.camera)  # the browser's first report
            client.camera.on_update(log.add)
            server.e2e_camera_logs[client.client_id] = log

        server.on_client_connect(on_connect)
    return server.e2e_camera_logs


def panel_left(page) -> float:
    """Left edge of viser's control panel (the largest positioned box on the right)."""
    box = page.evaluate("""() => {
      const vw = window.innerWidth, vh = window.innerHeight;
      let best = null;
      for (const e of document.querySelectorAll('div')) {
        const s = getComputedStyle(e), r = e.getBoundingClientRect();
        if ((s.position === 'absolute' || s.position === 'fixed') && r.width > 150 &&
            r.width < 0.6 * vw && r.right > 0.75 * vw && r.height > 0.3 * vh &&
            (!best || r.width * r.height > best.width * best.height)) best = r;
      }
      return best && {left: best.left, width: best.width};
    }""")
    canvas = page.locator("canvas").first.bounding_box()
    return box["left"] if box else canvas["x"] + canvas["width"] - PANEL_WIDTH


def inside_fraction(page, report, pts: np.ndarray) -> float:
    """Fraction of world points ``pts`` that the reported camera shows left of the panel."""
    _, c, wxyz, fov = report
    bb = page.locator("canvas").first.bounding_box()
    right = panel_left(page)
    pc = (np.asarray(pts, float) - c) @ tf.SO3(wxyz).as_matrix()  # OpenCV camera frame
    f = (bb["height"] / 2) / np.tan(fov / 2)
    z = np.where(pc[:, 2] > 1e-9, pc[:, 2], np.nan)
    x = bb["x"] + bb["width"] / 2 + f * pc[:, 0] / z
    y = bb["y"] + bb["height"] / 2 + f * pc[:, 1] / z
    ok = (pc[:, 2] > 1e-9) & (x >= bb["x"]) & (x <= right) & (y >= bb["y"]) \
        & (y <= bb["y"] + bb["height"])
    return float(np.mean(ok))


def extent(studio) -> np.ndarray:
    try:
        pts = np.asarray(studio.scene.extent_points(), float)
    except AttributeError as exc:
        pytest.fail(f"missing feature: SceneView.extent_points() ({exc})")
    assert pts.ndim == 2 and pts.shape[1] == 3 and len(pts) >= 4, pts.shape
    assert np.all(np.isfinite(pts))
    return pts


def wait_framed(page, log: CameraLog, pts: np.ndarray, since: float, timeout: float = 12.0):
    """Wait until the browser reports a camera (after ``since``) showing >= 95 % of ``pts``
    left of the panel; returns the last fraction seen."""
    seen = [0.0]

    def ok():
        r = log.since(since)
        seen[0] = inside_fraction(page, r, pts) if r is not None else 0.0
        return seen[0] >= 0.95

    wait_for(ok, timeout, 0.2)
    return seen[0]


def click(page, name, why: str) -> None:
    """Click the button ``name``; a missing button fails with ``why``."""
    button = page.get_by_role("button", name=name).first
    try:
        button.wait_for(state="visible", timeout=15_000)
    except playwright_sync.TimeoutError:
        pytest.fail(f"no visible button {name!r} ({why})")
    button.click()


def save_design(page) -> dict:
    """The design JSON that "Save design" downloads."""
    with page.expect_download(timeout=30_000) as dl:
        page.get_by_role("button", name="Save design").click()
    return json.loads(Path(dl.value.path()).read_text())


def upload(page, path: Path) -> None:
    with page.expect_file_chooser(timeout=15_000) as fc:
        page.get_by_role("button", name="Load design").click()
    fc.value.set_files(str(path))


def errors(studio, start: int = 0) -> list:
    return [n for n in studio.notifications[start:] if n[2]]


def text_field(page, label: str):
    """The input of the GUI text field labelled ``label`` (viser labels are not <label>s)."""
    return page.get_by_text(label, exact=True).first \
        .locator("xpath=ancestor::*[.//input][1]//input").first


def number_box(page, handle):
    """The number box of a viser number field (its own id) or slider (the box beside it)."""
    el = page.locator(f'[id="{handle._impl.uuid}"]')
    if el.evaluate("e => e.tagName") == "INPUT":
        return el
    return el.locator("xpath=..").locator("input[inputmode=decimal]")


def open_studio(path: Path):
    """Open ``path`` the way ``run_studio`` does (no autosave exists): (server, studio)."""
    design = design_mod.load_design(path)
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    return server, studio_mod.Studio(server, design, autosave_path_for(path, design.name))


def shifted(data: dict, offset, name: str) -> dict:
    data = json.loads(json.dumps(data))
    data["name"] = name
    for pose in data["poses"]:
        pose["position"] = list(np.asarray(pose["position"], float) + offset)
    return data


# --- 1. framing of the bundled examples ---------------------------------------------------------
@pytest.fixture(scope="module")
def readonly_assets(tmp_path_factory):
    """A read-only copy of assets/designs and assets/meshes (designs refer to ../meshes)."""
    root = tmp_path_factory.mktemp("ro") / "assets"
    for sub in ("designs", "meshes"):
        if (ASSETS / sub).exists():
            shutil.copytree(ASSETS / sub, root / sub)
    set_writable(root, False)
    yield root
    set_writable(root, True)


@pytest.mark.parametrize("example", EXAMPLES)
def test_open_and_frame_all_show_the_whole_design(example, readonly_assets, browser):
    """Each example opened from a read-only folder loads without errors and is framed left of
    the GUI panel on open and again by "Frame all" after the camera was moved away; the
    folder stays untouched."""
    before = tree_state(readonly_assets)
    server, studio = open_studio(readonly_assets / "designs" / example)
    page = None
    try:
        assert studio.worker.wait_idle(60)
        page, client, log = connect(server, browser)
        assert studio.worker.wait_idle(60)
        assert not errors(studio), studio.notifications
        assert "⚠" not in studio.panels.status.content, studio.panels.status.content
        pts = extent(studio)
        frac = wait_framed(page, log, pts, 0.0)
        assert frac >= 0.95, f"on open only {frac:.0%} of the extent is left of the panel"

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
        pages[0].get_by_role("combobox", name="Loop").click()
        option = pages[0].get_by_role("option", name=re.compile(r"^loop 4\b"))
        try:
            option.wait_for(state="visible", timeout=10_000)
        except playwright_sync.TimeoutError:
            pytest.fail("missing feature: no loop option labelled 'loop 4 ...'")
        option.click()
        assert wait_for(lambda: studio.state.design.loop == 4, 15)
        assert studio.worker.wait_idle(60)
        for pg in pages[1:]:
            playwright_sync.expect(pg.get_by_role("combobox", name="Loop")).to_have_value(
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
    env = {**os.environ, "XDG_DATA_HOME": str(xdg), "PYTHONUNBUFFERED": "1"}
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
        autosaves = list((xdg / "paraloop" / "autosave").glob("tv8-*.json"))
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
    assert "ok" in status and "⚠" not in status, status
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
    of its extent left of the panel); Undo restores the previous design."""
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
        pts = extent(app)
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
