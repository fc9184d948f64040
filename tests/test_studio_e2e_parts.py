"""End-to-end test in real headless Chromium of what you see is what you print (issue 28): each
example opened from a read-only copy (one browser for all five) shows its printed parts
(built in the background after the opening), framed when they arrive so that they cover at
least :data:`MIN_COVER` of the view left of the panel (pixels of screenshots with the parts
and with no linkage) with the free targets in view and the status one plain sentence; they
are the parts *Export all* writes (per link the volume and box of the scene's meshes against
``report.json``, mm over the export's mm per design unit); for tv8 they cover more than the
solid links.

Skipped when chromium or playwright is missing, except under ``CI=true`` where that fails.
"""

from __future__ import annotations

import io
import zipfile
from pathlib import Path

import numpy as np
import pytest
import scipy.spatial
import trimesh
from PIL import Image

from app.exports import export_zip
from app.scene import LINKAGE, PARTS
from tests import browser_support
from tests.browser_support import (
    EXAMPLES,
    connect,
    inside_fraction,
    open_studio,
    panel_left,
    wait_for,
    wait_framed,
)
from tests.test_studio_plain import sentence_problems

pytestmark = pytest.mark.browser
browser = browser_support.browser  # the fixture
readonly_assets = browser_support.readonly_assets  # the fixture

#: Least share of the visible scene the printed parts cover at the opening framing (issue
#: 28's done-when; measured 8.6 - 31 % on the five examples, tv8 the least).
MIN_COVER = 0.04
#: A pixel differs between the screenshots when a channel moves by more than this (of 255):
#: above the renderer's noise, far below the parts' contrast with the background.
PIXEL_STEP = 24


def scene_shot(page) -> np.ndarray:
    """The scene left of the GUI panel as an ``(H, W, 3)`` int array."""
    bb = page.locator("canvas").first.bounding_box()
    width = panel_left(page) - bb["x"]
    png = page.screenshot(clip={"x": bb["x"], "y": bb["y"], "width": width,
                                "height": bb["height"]})
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), int)


def solid(mask: np.ndarray) -> np.ndarray:
    """``mask`` ``(H, W)`` without its features thinner than 3 px (a 3 x 3 opening): the
    renderer's one-pixel shifts of lines and grid between screenshots, and hairlines."""
    def shifts(m):
        p = np.pad(m, 1)
        return [p[i:i + m.shape[0], j:j + m.shape[1]] for i in range(3) for j in range(3)]
    return np.logical_or.reduce(shifts(np.logical_and.reduce(shifts(mask))))


def parts_nodes(page, visible: bool) -> bool:
    """Whether the page holds the six printed parts' nodes, all ``visible`` or all hidden."""
    page.wait_for_timeout(50)  # the sync API hands the page's websocket frames over here
    nodes = [v for k, v in page.scene.nodes.items() if k.startswith("/loop/parts/")]
    return len(nodes) == 6 and all(v["visible"] == visible for v in nodes)


def cover(shot: np.ndarray, none: np.ndarray) -> float:
    """Share of the pixels that differ between ``shot`` and the scene without a linkage."""
    return float(np.mean(solid(np.abs(shot - none).max(axis=-1) > PIXEL_STEP)))


def shot_with(app, page, layer: str, shown: bool) -> np.ndarray:
    """:func:`scene_shot` once ``layer`` is ``shown`` (or hidden) and the page has drawn."""
    app.panels.layers[layer].value = shown
    assert app.worker.wait_idle(30)
    if layer == PARTS:
        assert wait_for(lambda: parts_nodes(page, shown), 10)
    page.wait_for_timeout(1500)  # rendered
    return scene_shot(page)


def example_covers(browser, path: Path) -> dict[str, float]:
    """The example ``path`` opened as ``run_studio`` does, in a page: its parts arrive, the
    page is framed on them with the free targets in view and the status sentence plain;
    the parts' cover (and for tv8 the solid links'); the parts checked against the export."""
    server, app = open_studio(path)
    page = None
    try:
        page, _, log = connect(server, browser)
        for button in page.locator("[class*=Notification-closeButton]").all():
            button.click()  # the browser's own notes (software WebGL) cover the scene
        assert app.printview.wait_idle(180) and app.worker.wait_idle(60)
        parts = app.printview.parts
        assert parts is not None, (path.name, app.printview.card.text.content)
        assert wait_for(lambda: parts_nodes(page, True), 30), sorted(page.scene.nodes)
        assert wait_framed(page, log, app.scene.object_shot().points, 0.0) >= 0.95, path.name
        free = [p for i, p in enumerate(app.scene.target_positions)
                if i not in app.state.design.locked]
        assert inside_fraction(page, log.reports[-1], np.array(free)) == 1.0, path.name
        sentence = app.panels.status.content.strip("*")
        assert not sentence_problems(sentence), sentence
        page.wait_for_timeout(1500)  # rendered
        shots = {"parts": scene_shot(page)}
        if path.name == "tv8.json":  # the solid links at their true radius
            shots["solid links"] = shot_with(app, page, PARTS, False)
        none = shot_with(app, page, LINKAGE, False)
        assert not page.js_errors, page.js_errors
        same_as_export(app, parts)
        return {k: cover(v, none) for k, v in shots.items()}
    finally:
        if page is not None:
            page.context.close()
        app.close()
        server.stop()


def test_printed_parts_fill_the_opening_view_and_match_the_export(browser, readonly_assets,
                                                                  monkeypatch):
    """Every example (:func:`example_covers`): the parts cover at least :data:`MIN_COVER`
    of the view; tv8's more than twice its solid links."""
    monkeypatch.setenv("PARALOOP_STUDIO_PARTS", "1")
    covers = {name: example_covers(browser, readonly_assets / "designs" / name)
              for name in EXAMPLES}
    print("; ".join(f"{name}: " + ", ".join(f"{k} cover {100 * v:.1f} %" for k, v in c.items())
                    for name, c in covers.items()))
    assert all(c["parts"] >= MIN_COVER for c in covers.values()), covers
    assert covers["tv8.json"]["parts"] >= 2.0 * covers["tv8.json"]["solid links"], covers


def same_as_export(app, parts) -> None:
    """The parts *Export all* writes are the scene's: per link the volume and, for a link of
    one part, the scene's mesh scaled by the export's mm per unit is the exported STL's
    tessellation (every 50th vertex within 0.01 mm of one of the STL's; the scene's vertices
    are float32. An
    oriented box was compared before: trimesh's box search is a heuristic that two such
    nearly equal meshes can send to boxes 3 % apart)."""
    _, data, report = export_zip(app.solution, app.state.fab)
    stls = zipfile.ZipFile(io.BytesIO(data))
    scale = report["scale_mm_per_unit"]
    assert scale == pytest.approx(parts.scale, rel=1e-9)
    ground = report["base"]["grounded_link"] if report.get("base") else 0
    by_link: dict[int, list[dict]] = {}
    for p in report["parts"]:
        if p["role"] == "link piece":  # printed in pieces: its assembled link stands for them
            continue
        by_link.setdefault(p["link"] if 0 <= p["link"] < 6 else ground, []).append(p)
    handles = dict(app.scene.parts)
    assert sorted(handles) == sorted(by_link)
    for link, exported in by_link.items():
        h = handles[link]
        mesh = trimesh.Trimesh(np.asarray(h.vertices, float) * scale, h.faces)
        volume = sum(p["volume_cm3"] for p in exported) * 1e3
        assert mesh.volume == pytest.approx(volume, rel=0.01), link
        if len(exported) == 1:
            stl = trimesh.load(io.BytesIO(stls.read(f"{exported[0]['name']}.stl")),
                               file_type="stl")
            off = scipy.spatial.cKDTree(stl.vertices).query(mesh.vertices[::50])[0]
            assert off.max() < 0.01, (link, off.max())
