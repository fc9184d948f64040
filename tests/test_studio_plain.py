"""Headless tests of the studio in a designer's words and view (issue 28): the status sentence
(length, no symbols, no e-notation) on every example opened from a read-only copy, every
control labelled plainly and with a tooltip, no command-line option in any GUI text, pose
labels that never overlap at the opening framing, the construction aids hidden at start and
the hook that draws per-link meshes."""

from __future__ import annotations

import ast
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import viser
from hypothesis import given, settings
from hypothesis import strategies as st

from app import exports
from app import labels as labels_mod
from app import status as status_mod
from app import studio as studio_mod
from app.notices import Notices
from app.scene import CONSTRUCTION, HIDDEN_AT_START
from app.wording import PHRASES, gui_text
from paraloop_core import design as design_mod
from paraloop_core.algebra import dq, poly
from paraloop_core.errors import (
    DesignFileError,
    FitError,
    InterpolationError,
    NonGenericMotionError,
)
from paraloop_core.linkage import loops
from tests import test_studio_server
from tests.test_studio_server import gizmo, settle

ROOT = Path(__file__).resolve().parent.parent
DESIGNS = ROOT / "assets" / "designs"
EXAMPLES = sorted(p.stem for p in DESIGNS.glob("*.json"))
studio = test_studio_server.studio  # the fixture: tv8 with S0..S2 locked
#: Symbols a designer should not meet in a status sentence or a control's label.
SYMBOLS = re.compile(r"\b(rho|mu|p|q|w0|d)\b|[ρμ∞]|\(p\)|\bx (loop|joint)\b", re.IGNORECASE)
E_NOTATION = re.compile(r"\d[eE][+-]?\d")


def sentence_problems(text: str) -> list[str]:
    """What is wrong with a status sentence (markdown bold allowed): too long, a symbol, a
    number in e-notation, a command-line option, more than one line."""
    plain = text.strip().strip("*")
    out = []
    if len(plain) > status_mod.HEADLINE_MAX:
        out.append(f"{len(plain)} characters")
    if SYMBOLS.search(plain):
        out.append(f"symbol {SYMBOLS.search(plain).group(0)!r}")
    if E_NOTATION.search(plain):
        out.append("e-notation")
    if "--" in plain or "\n" in plain:
        out.append("an option or a second line")
    return out


@pytest.fixture(scope="module")
def readonly_designs(tmp_path_factory):
    """A read-only copy of assets/designs and assets/meshes."""
    root = tmp_path_factory.mktemp("ro") / "assets"
    for sub in ("designs", "meshes"):
        shutil.copytree(ROOT / "assets" / sub, root / sub)
    paths = [root, *root.rglob("*")]
    for p in reversed(paths):
        p.chmod(0o555 if p.is_dir() else 0o444)
    yield root / "designs"
    for p in paths:
        p.chmod(0o755 if p.is_dir() else 0o644)


def overlapping(view: labels_mod.View, anchors: np.ndarray, texts: list[str]) -> list:
    """Pairs of label boxes that overlap on screen."""
    b = labels_mod.boxes(view, anchors, texts)
    hit = labels_mod.overlaps(b, b) & ~np.eye(len(b), dtype=bool)
    return [(texts[i], texts[j]) for i, j in zip(*np.nonzero(np.triu(hit)), strict=True)]


def opening_view(app) -> labels_mod.View:
    cam = app.server.initial_camera
    return labels_mod.View(np.asarray(cam.position), np.asarray(cam.look_at), float(cam.fov),
                           studio_mod.camera.DEFAULT_SIZE)


@pytest.mark.parametrize("name", EXAMPLES)
def test_every_example_opens_in_plain_words(name, readonly_designs):
    """Opened from a read-only folder: solved without notices, the linkage drawn as solid
    links with the construction aids hidden, the status one plain sentence with the printed
    size, the details folded below, the pose labels apart at the opening framing."""
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = studio_mod.Studio(server, design_mod.load_design(readonly_designs / f"{name}.json"))
    try:
        settle(app)
        assert app.error is None and not app.notifications, app.notifications
        assert len(app.scene.gizmos) == len(app.state.design.poses)
        text = app.panels.status.content
        assert not sentence_problems(text), (text, sentence_problems(text))
        # the printed size, and the bar width where the on-screen loop holds the export's
        # joints (else the export realizes it again with roomier joints: the size alone)
        size, bar = exports.print_estimate(app.solution.realization, app.state.fab)
        if bar is None:
            assert re.search(rf"Collision-free loop found - about {size:.0f} mm across when "
                             "printed", text), text
        else:
            assert re.search(rf"Collision-free loop found - {size:.0f} mm across, "
                             r"[\d.]+ mm bars", text), text
        assert "Realized loop" in app.panels.details.content  # the numbers, folded
        h = app.scene.handles
        assert all(h[k].visible for k in ("bars", "elbows", "joints", "path"))
        assert not any(h[k].visible for k in ("facts", "axes", "ellipsoid", "frames"))
        assert not h["current"].show_axes
        lbl = app.scene.labels
        assert not overlapping(opening_view(app), np.array([x.position for x in lbl]),
                               [x.text for x in lbl])
    finally:
        app.close()
        server.stop()


def test_the_sentence_for_failures_drags_and_searches(studio, monkeypatch):
    """A drag preview, a failed search and an unsolvable pose give plain sentences that say
    what to do; the numbers stay in the details."""
    from app import solver as solver_mod
    from paraloop_core import pipeline

    seen = []
    show = studio.status._show
    monkeypatch.setattr(studio.status, "_show", lambda text, detail=None: (
        seen.append(text), show(text, detail)))
    p = studio.state.design.poses[3].position
    gizmo(studio, 3, position=p + 0.01, phases=("update",))
    assert seen[-1].startswith("Moving S3")
    monkeypatch.setattr(pipeline, "FIRST_ATTEMPT_WORK", 1)
    monkeypatch.setattr(pipeline, "FALLBACK_WORK", 1)
    monkeypatch.setattr(pipeline, "PREVIEW_WORK", 1)
    monkeypatch.setattr(solver_mod, "QUICK_WORK", 1)
    gizmo(studio, 3, position=p + 0.2)
    assert "Searching for a collision-free loop..." in seen
    assert seen[-1].startswith("No collision-free loop for this pose: move S3 back")
    s0 = studio.state.design.poses[0]
    gizmo(studio, 3, position=s0.position, wxyz=s0.wxyz)
    assert seen[-1].startswith("Two target poses coincide: move S3")
    assert all(not sentence_problems(s) for s in seen), [s for s in seen if
                                                         sentence_problems(s)]


@pytest.mark.parametrize("exc", [
    InterpolationError("poses 0 and 3 coincide", "coincident"),
    InterpolationError("no real interpolant: discriminant < 0, mu = 1e-300", "no-real"),
    NonGenericMotionError("non-generic motion: rho = 2e-17", "real-root"),
    FitError("motion evolution needs at least 5 target poses", "too-few-poses"),
    FitError("no convergence after 1e+06 iterations", "no-convergence"),
    DesignFileError("poses", "needs 4"), ValueError("anything --size-mm 1e-9")])
@pytest.mark.parametrize("moved", [None, 0, 123])
def test_error_sentences_are_plain(exc, moved):
    for shown in (False, True):
        text = status_mod.error_headline(exc, moved, shown)
        assert not sentence_problems(text), text


def test_plain_numbers_never_use_e_notation():
    for x in (1e-9, 3.4e-5, 0.5, 12345.678, 6.02e23):
        assert not E_NOTATION.search(status_mod.plain(x)) and float(status_mod.plain(x)) > 0


def test_every_control_has_a_tooltip_and_a_plain_label(studio):
    """All inputs and buttons (Locks, Drive, Fabrication included) explain themselves; their
    labels carry no symbol (the paper's symbols live in the tooltips)."""
    handles = [h for h in studio.server.gui._gui_input_handle_from_uuid.values()
               if not h._impl.removed and hasattr(h, "hint")]  # (progress bars have none)
    assert len(handles) > 60
    assert not [h.label for h in handles if not (h.hint or "").strip()]
    assert not [h.label for h in handles if SYMBOLS.search(h.label or "")]
    hints = " ".join(h.hint for h in handles)
    assert "Sec. 4.2" in hints and "μ" in hints and "ρ" in hints  # where the paper is


def _core_texts() -> list[str]:
    """Every string literal of ``paraloop_core/fabrication`` (f-strings' fields as {})."""
    out = []
    for path in sorted((ROOT / "paraloop_core" / "fabrication").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.JoinedStr):
                out.append("".join(v.value if isinstance(v, ast.Constant) else "{}"
                                   for v in node.values))
            elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                out.append(node.value)
    return out


def test_core_texts_reach_the_page_without_command_line_options():
    texts = _core_texts()
    flagged = [t for t in texts if re.search(r"--[a-z]", t)]
    assert flagged, "the core names no option: this test would check nothing"
    for phrase, _ in PHRASES:  # the translations stay in step with the core's texts
        assert any(phrase in t for t in texts), phrase
    assert not [gui_text(t) for t in flagged if re.search(r"--[a-z]", gui_text(t))]
    notices = Notices(_NoClients())
    notices.notify("Exported, with notes", flagged[0], cause="x")
    assert "--" not in notices.log[-1][1]


class _NoClients:
    def get_clients(self) -> dict:
        return {}


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 12), st.integers(0, 2**32 - 1), st.floats(1e-3, 1e3))
def test_label_boxes_never_overlap_nor_cover_a_target(n, seed, scale):
    """Any targets (clustered, coincident, behind one another): the placed boxes keep apart
    and leave every target's centre free, seen from the view they were placed for."""
    rng = np.random.default_rng(seed)
    targets = rng.normal(size=(n, 3)) * scale * rng.choice([1e-3, 0.1, 1.0], size=(n, 1))
    view = labels_mod.View(np.array([3.0, -4.0, 2.0]) * scale, np.zeros(3), np.radians(50.0),
                           (1280.0, 800.0))
    texts = [f"S{i} #{i + 1}" + " (locked)" * (i % 2) for i in range(n)]
    anchors = labels_mod.place(targets, texts, view)
    assert not overlapping(view, anchors, texts)
    px, _ = view.project(targets)
    spots = np.concatenate([px, px], axis=-1)
    assert not labels_mod.overlaps(labels_mod.boxes(view, anchors, texts), spots).any()


def test_construction_aids_start_hidden_and_show_on_request(studio):
    assert studio.state.hidden == set(HIDDEN_AT_START) and "Trajectory" not in HIDDEN_AT_START
    for name in CONSTRUCTION:
        assert studio.panels.layers[name].value == (name not in HIDDEN_AT_START), name
    studio.panels.layers["Inertia ellipsoid"].value = True
    studio.panels.layers["Moving frames"].value = True
    settle(studio)
    h = studio.scene.handles
    assert h["ellipsoid"].visible and h["frames"].visible and h["current"].show_axes


def _boxes(jf, points):
    """Small boxes around each link's bar (home frame): stand-ins for printable parts."""
    out = []
    for i in range(6):
        a, b = points[2 * i], points[2 * i + 1]
        box = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
        out.append((a + np.outer(box[:, 0], b - a) + 0.01 * box,
                    np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5]])))
    return out


def test_per_link_meshes_replace_the_solid_links_and_follow_the_slider(studio):
    real = studio.solution.realization
    with studio.server.atomic():
        studio.scene.set_parts(real.joint_factors, _boxes(real.joint_factors, real.points))
    studio.panels.u.value = 0.3
    settle(studio)
    h, parts = studio.scene.handles, studio.scene.parts
    assert len(parts.handles) == 6 and all(m.visible for _, m in parts.handles)
    assert not h["bars"].visible and not h["joints"].visible
    pose = loops.link_poses(real.joint_factors, poly.param_to_t(np.array([0.3])))[0]
    pos, _ = dq.to_pos_wxyz(pose)
    assert np.allclose(parts.handles[2][1].position, pos[2], atol=1e-6)
    # another loop on screen: the meshes are not its parts, the solid links return
    studio.panels.loop.value = studio.panels.loop.options[(studio.state.design.loop + 1) % 9]
    settle(studio)
    assert not any(m.visible for _, m in parts.handles) and h["bars"].visible
    with studio.server.atomic():
        studio.scene.set_parts(real.joint_factors, None)
    assert not parts


def test_last_moved_pose_is_named(studio):
    gizmo(studio, 3, position=studio.state.design.poses[3].position + 0.01)
    assert studio.state.last_moved == 3
    studio.panels.name.value = "renamed"
    assert studio.state.last_moved is None
