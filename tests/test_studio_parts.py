"""Headless tests of what you see is what you print (issue 28): the printed parts drawn in
place of the solid links after a release (built in a child process, ``app.printview``), the
line shown while they are being built, the *Printed object* card and its physics check, and a
refusal shown as one plain sentence."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
import viser
from test_studio_server import click, gizmo

from app import studio as studio_mod
from app.scene import LINKAGE, PARTS
from paraloop_core import design as design_mod

DESIGNS = Path(__file__).resolve().parent.parent / "assets" / "designs"


def wait_for(pred, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while not pred() and time.monotonic() < end:
        time.sleep(0.02)
    return pred()


def settle_parts(app, timeout: float = 180.0) -> None:
    """The worker idle, the printed parts built (or refused) and drawn."""
    assert app.worker.wait_idle(60) and app.printview.wait_idle(timeout)
    assert app.worker.wait_idle(60)


@pytest.fixture
def tv8(monkeypatch, tmp_path):
    monkeypatch.setenv("PARALOOP_STUDIO_PARTS", "1")
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = studio_mod.Studio(server, design_mod.load_design(DESIGNS / "tv8.json"),
                            tmp_path / "tv8.autosave.json")
    settle_parts(app)
    yield app
    app.close()
    server.stop()


def shown(handles) -> list[bool]:
    return [h.visible for _, h in handles]


def solid_links_shown(app) -> bool:
    return all(app.scene.handles[k].visible for k in ("bars", "elbows", "joints"))


def test_parts_replace_the_solid_links_and_move_with_the_slider(tv8):
    scene, pv = tv8.scene, tv8.printview
    assert pv.drawn is not None and pv.drawn[0] is tv8.solution.realization
    assert len(scene.parts) == 6 and all(shown(scene.parts)) and any(shown(scene.hardware))
    assert not solid_links_shown(tv8)
    assert not pv.card.building.visible
    # the meshes are the export's parts in design units: their extent is the printed size
    parts = pv.parts
    verts = np.concatenate([m[0] for m in parts.meshes if m is not None])
    size = parts.report["sizing"]["size_mm"]
    assert np.max(np.ptp(verts, axis=0)) * parts.scale >= 0.9 * size
    before = [h.wxyz.copy() for _, h in scene.parts]
    tv8.panels.u.value = (tv8.state.u + 0.3) % 1.0
    assert tv8.worker.wait_idle(30)
    assert any(not np.allclose(h.wxyz, b) for (_, h), b in zip(scene.parts, before,
                                                                 strict=True))
    # hidden on request: the solid links stand in
    tv8.panels.layers[PARTS].value = False
    assert tv8.worker.wait_idle(30)
    assert not any(shown(scene.parts)) and solid_links_shown(tv8)
    tv8.panels.layers[LINKAGE].value = False
    tv8.panels.layers[PARTS].value = True
    assert tv8.worker.wait_idle(30)
    assert not any(shown(scene.parts)) and not tv8.scene.handles["bars"].visible


def test_drag_shows_solid_links_then_marks_and_draws_the_new_parts(tv8):
    scene, pv = tv8.scene, tv8.printview
    old = pv.drawn
    new = tv8.state.design.poses[3].position + np.array([0.03, -0.02, 0.01])
    gizmo(tv8, 3, position=new, phases=("start", "update"))  # dragging: the fast preview
    assert not any(shown(scene.parts)) and solid_links_shown(tv8)
    gizmo(tv8, 3, position=new, phases=("end",))
    real = tv8.solution.realization
    assert real is not None and real is not old[0]
    # while they are built: marked under the status, the card says it is out of date
    assert wait_for(lambda: pv.card.building.visible, 10)
    assert "Building printed parts" in pv.card.building.content
    assert pv.card.text.content.startswith("*(For the design before")
    assert pv.card.physics_button.disabled and solid_links_shown(tv8)
    settle_parts(tv8)
    assert pv.drawn[0] is tv8.solution.realization and all(shown(scene.parts))
    assert not pv.card.building.visible and not solid_links_shown(tv8)
    assert pv.timings and all(t > 0 for t in pv.timings)


def test_summary_card_states_the_reports_figures_and_runs_the_physics_check(tv8):
    pv = tv8.printview
    r, text = pv.parts.report, pv.card.text.content
    links = r["stiffness"]["links"]
    thin = min(e["width_mm"] for e in links)
    for want in (f"{r['sizing']['size_mm']:.0f} mm across",
                 f"{r['print_layout']['plates']} plate",
                 f"**Thinnest bar:** {thin:.1f} mm wide",
                 "M3 x", "screws with lock nuts and washers",
                 f"{1e3 * sum(r['drive']['link_masses_kg']):.0f} g in all",
                 f"{r['drive']['peak_torque_n_m']:.2g} N·m",
                 "**Stands:** yes" if r["base"]["stands"] else "**Stands:** no",
                 "**Collision check:** passed" if r["verification"]["ok"] else "failed"):
        assert want in text, (want, text)
    assert "--" not in text and "Traceback" not in text
    assert not pv.card.physics_button.disabled
    click(pv.card.physics_button)
    assert "Running the physics check" in pv.card.physics.content
    settle_parts(tv8)
    assert pv.card.physics.content.startswith("**Physics check"), pv.card.physics.content
    assert "N·m" in pv.card.physics.content


def test_a_refusal_is_one_plain_sentence(tv8):
    pv = tv8.printview
    errors = len([n for n in tv8.notifications if n[2]])
    tv8.fabrication.inputs["size_mm"].value = 20.0  # far too small for M3 screws
    settle_parts(tv8)
    text = pv.card.text.content
    assert text.startswith("**These parts cannot be printed:**"), text
    assert "no realization of this design can be printed" in text
    assert "Traceback" not in text and "Error" not in text and len(text) < 400
    assert pv.drawn is None and len(tv8.scene.parts) == 0 and solid_links_shown(tv8)
    assert not pv.card.building.visible and pv.card.physics_button.disabled
    assert len([n for n in tv8.notifications if n[2]]) == errors  # no internal error
