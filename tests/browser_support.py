"""What the real-browser tests share: Debian's Chromium via Playwright, its flags, waiting,
pages and their camera reports, the scene a page received, toasts, read-only example copies.

Importing this module skips the importing test module when chromium or playwright is missing,
except under ``CI=true`` where that fails (a suite that skips its real parts is a defect).
Never run ``playwright install``: it cannot download browsers here.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import socket
import time
from collections.abc import Iterator
from pathlib import Path

import msgspec
import numpy as np
import pytest
import viser
import zstandard
from viser import transforms as tf

from app import studio as studio_mod
from app.labels import box_sizes
from app.state import autosave_path_for
from paraloop_core import design as design_mod
from paraloop_core.design import Design

CHROMIUM = os.environ.get("CHROMIUM", "/usr/bin/chromium")
_CI = os.environ.get("CI", "").lower() == "true"
try:
    from playwright import sync_api as playwright_sync
except ImportError:  # pragma: no cover - depends on the machine
    if _CI:
        raise
    pytest.skip("playwright is not installed", allow_module_level=True)
if not Path(CHROMIUM).exists():
    if _CI:
        raise RuntimeError(f"{CHROMIUM} missing under CI=true (apt-get install chromium)")
    pytest.skip(f"{CHROMIUM} not installed (apt-get install -y chromium)",
                allow_module_level=True)

CHROMIUM_ARGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
]



def wait_for(pred, timeout: float = 10.0, dt: float = 0.05) -> bool:
    """Poll ``pred`` until true or ``timeout`` seconds; its last value."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(dt)
    return pred()


@contextlib.contextmanager
def serve(design: Design, autosave: Path | None = None) -> Iterator[studio_mod.Studio]:
    """A studio on ``design`` served on a free port of 127.0.0.1, settled; stopped after."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    studio = studio_mod.Studio(server, design, autosave)
    try:
        assert studio.worker.wait_idle(60)
        yield studio
    finally:
        studio.close()
        server.stop()


ROOT = Path(__file__).resolve().parent.parent
ASSETS = ROOT / "assets"
EXAMPLES = sorted(p.name for p in (ASSETS / "designs").glob("*.json"))
TV8 = ASSETS / "designs" / "tv8.json"
VIEWPORT = {"width": 1280, "height": 800}
PANEL_WIDTH = 320  # viser's control panel, when its element cannot be found


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


@pytest.fixture(scope="module")
def browser():
    with playwright_sync.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)
        yield b
        b.close()


def new_page(browser, url: str, viewport=None):
    """A page in its own context at ``url`` (1280x800, downloads on); ``page.js_errors``,
    ``page.scene`` (:class:`SceneLog`)."""
    ctx = browser.new_context(viewport=viewport or VIEWPORT, accept_downloads=True)
    page = ctx.new_page()
    page.js_errors = []  # type: ignore[attr-defined]
    page.on("pageerror", lambda e: page.js_errors.append(str(e)))
    page.scene = SceneLog(page)  # type: ignore[attr-defined]
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


def extent(studio, opening: bool = False) -> np.ndarray:
    """The points a framing shows: *Frame all*'s, or with ``opening`` the opening one's."""
    scene = studio.scene
    pts = np.asarray((scene.object_shot() if opening else scene.all_shot()).points, float)
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


class SceneLog:
    """The scene a page received over its websocket, decoded from viser's wire format
    (``[8 B msgpack size][8 B compressed size][zstd msgpack][binary buffers]``, see
    ``viser.infra._infra``): the live nodes by name with their message type, props,
    visibility and position, as the page's client holds them."""

    def __init__(self, page) -> None:
        self.nodes: dict[str, dict] = {}
        page.on("websocket", lambda ws: ws.on("framereceived", self._frame))

    def _frame(self, payload) -> None:
        if not isinstance(payload, bytes) or len(payload) < 16:
            return
        size, packed = (int.from_bytes(payload[k:k + 8], "little") for k in (0, 8))
        data = zstandard.ZstdDecompressor().decompress(payload[16:16 + packed],
                                                       max_output_size=size)
        for m in msgspec.msgpack.decode(data).get("messages", ()):
            name = m.get("name") if isinstance(m, dict) else None
            if not isinstance(name, str):
                continue
            if m.get("type") == "RemoveSceneNodeMessage":
                for key in [k for k in self.nodes if k == name or k.startswith(name + "/")]:
                    del self.nodes[key]
            elif "props" in m:
                self.nodes[name] = {"type": m["type"], "props": dict(m["props"]),
                                    "visible": True}
            elif name in self.nodes and m.get("type") == "SetSceneNodeVisibilityMessage":
                self.nodes[name]["visible"] = bool(m["visible"])
            elif name in self.nodes and m.get("type") == "SetPositionMessage":
                self.nodes[name]["position"] = np.asarray(m["position"], float)
            elif name in self.nodes and m.get("type") == "SceneNodeUpdateMessage":
                self.nodes[name]["props"].update(m["updates"])

    def labels(self) -> dict[str, dict]:
        """The live label nodes (name -> node)."""
        return {k: v for k, v in self.nodes.items() if v["type"] == "LabelMessage"}


def toasts(page) -> list[str]:
    """The texts of the notifications (toasts) the page shows."""
    return page.locator("[class*=Notification-root]").all_inner_texts()


def label_boxes(page, report, labels: dict[str, dict]) -> np.ndarray:
    """Screen boxes ``(N, 4)`` (x0, y0, x1, y1, CSS px) of ``labels`` (:meth:`SceneLog.labels`,
    centre-anchored) seen by a reported camera (``CameraLog`` entry), sized as
    :func:`app.labels.box_sizes` estimates them."""
    _, c, wxyz, fov = report
    bb = page.locator("canvas").first.bounding_box()
    pts = np.array([v["position"] for v in labels.values()], float).reshape(-1, 3)
    pc = (pts - c) @ tf.SO3(wxyz).as_matrix()  # OpenCV camera frame
    f = (bb["height"] / 2) / np.tan(fov / 2)
    centre = np.stack([bb["x"] + bb["width"] / 2 + f * pc[:, 0] / pc[:, 2],
                       bb["y"] + bb["height"] / 2 + f * pc[:, 1] / pc[:, 2]], axis=-1)
    half = 0.5 * box_sizes([v["props"]["text"] for v in labels.values()])
    return np.concatenate([centre - half, centre + half], axis=-1)


def drag_gizmo(page, client, gizmo, pixels: float, steps: int = 10, rank: int = 0) -> None:
    """A real mouse drag of ``gizmo``'s arrow that looks longest on screen (``rank`` 1, 2:
    the next ones; arrows whose drag leaves the scene left of the panel last), ``pixels``
    along it, seen by ``client``'s camera; the mouse is still down when this returns (call
    ``page.mouse.up()`` to release)."""
    cam = client.camera
    rot, c = tf.SO3(cam.wxyz).as_matrix(), cam.position.copy()
    bb = page.locator("canvas").first.bounding_box()
    f = (bb["height"] / 2) / np.tan(cam.fov / 2)

    def proj(pw):
        pc = rot.T @ (np.asarray(pw, float) - c)
        return np.array([bb["x"] + bb["width"] / 2 + f * pc[0] / pc[2],
                         bb["y"] + bb["height"] / 2 + f * pc[1] / pc[2]])

    centre, axes, s = gizmo.position.copy(), tf.SO3(gizmo.wxyz).as_matrix(), gizmo.scale
    right = panel_left(page)

    def on_canvas(p) -> bool:
        return bb["x"] < p[0] < right and bb["y"] < p[1] < bb["y"] + bb["height"]

    def arrow(k: int) -> tuple[float, np.ndarray, np.ndarray]:
        """(on screen length or -1 when the drag would leave the scene, start, direction)."""
        d = proj(centre + s * axes[:, k]) - proj(centre)
        length = float(np.linalg.norm(d))
        start, d = proj(centre + 0.9 * s * axes[:, k]), d / length
        ok = on_canvas(start) and on_canvas(start + pixels * d)
        return (length if ok else -1.0), start, d

    _, start, d = sorted((arrow(k) for k in range(3)), key=lambda r: -r[0])[rank]
    page.mouse.move(*start)
    page.mouse.down()
    for k in range(1, steps + 1):
        page.mouse.move(*(start + pixels * d * k / steps))
        time.sleep(0.03)
