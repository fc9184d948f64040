"""The studio's GUI panels. Handlers only edit the state and ask the worker for an update;
:meth:`Panels.sync` (worker thread) writes values back without re-triggering the handlers."""

from __future__ import annotations

import contextlib
import dataclasses
import threading
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import numpy as np
import viser

from app.panels.effector import EffectorPanel
from app.panels.evolution import EvolutionPanel
from app.panels.realization import RealizationPanel
from app.panels.view import ViewPanel
from app.scene import design_scale
from app.state import rescaled
from app.status import unit_factor
from app.worker import FRAME, FULL
from paraloop_core.algebra import dq, poly
from paraloop_core.design import Design, Pose
from paraloop_core.linkage import loops, singularity
from paraloop_core.motion.evolution import evolution_settings

if TYPE_CHECKING:
    from app.host import StudioHost

_sync = threading.local()


def loop_label(k: int, singularity: float | None = None, status: str = "") -> str:
    """Readable dropdown label of loop ``k``, e.g. ``'loop 4 · angle-symmetric · score 77'``:
    its kind and its score, the singularity measure S (min over the cycle, Sec. 4.4; higher
    is farther from jamming), with a warning word when it is (near) singular."""
    text = f"loop {k} · {loops.LOOP_KINDS[k]}"
    if singularity is not None:
        text += f" · score {score_text(singularity)}"
        if status != "ok":
            text += f" ({status})"
    return text


def loop_of_label(label: str) -> int:
    """The loop index of a :func:`loop_label`."""
    return int(label.split("·")[0].split()[1])


def score_text(value: float) -> str:
    """A singularity score for people: 77, 3.4, 0.052, 2e-07."""
    if value >= 10:
        return f"{value:.0f}"
    if value >= 1e-3:
        return f"{value:.2g}"
    return f"{value:.0e}"


#: Smallest half-range of the mu slider; it widens to show any mu of the design.
MU_RANGE = 5.0
#: The Motion folder's dropdown entries for the design file's values.
METHOD_NAMES = {"four-pose": "Through 4 poses", "fit": "Fitted to all poses"}
FAMILY_NAMES = ("first", "second")
CRITERION_NAMES = {"length": "Shortest path", "base-axes": "Base joints through targets",
                   "end-axes": "End joints through targets",
                   "extra-poses": "Closest to extra poses", "smooth-drive": "Smoothest drive"}


def pose_in_gap(design: Design, sol: Any) -> Pose:
    """A pose for *Add pose*: on the motion of ``sol``, halfway across the largest gap between
    visited targets (no solution of ``design``: beside its last pose)."""
    if sol is None or len(sol.pose_parameters) != len(design.poses):
        last = design.poses[-1]
        return Pose(last.position + 0.1 * design_scale(design), last.wxyz.copy())
    u = np.sort(poly.t_to_param(sol.pose_parameters))
    gaps = np.diff(np.append(u, u[0] + 1.0))
    k = int(np.argmax(gaps))
    pos, wxyz = dq.to_pos_wxyz(poly.evaluate_pose(
        sol.motion, poly.param_to_t((u[k] + 0.5 * gaps[k]) % 1.0)))
    return Pose(pos, wxyz)


def value_of(names: dict[str, str], label: str) -> str:
    """The design file's value of a dropdown entry ``label``."""
    return next(k for k, v in names.items() if v == label)


def mu_range(mu: float | None) -> float:
    """Half-range of the mu slider that shows ``mu`` (a whole number >= :data:`MU_RANGE`)."""
    return MU_RANGE if mu is None else float(max(MU_RANGE, np.ceil(1.5 * abs(mu))))


def handler(fn: Any) -> Any:
    """Wrap a GUI callback so that it ignores events caused by :func:`writing_back`."""

    def wrapped(event: Any) -> None:
        if not getattr(_sync, "active", False):
            fn(event)

    return wrapped


@contextlib.contextmanager
def writing_back() -> Iterator[None]:
    """Widget values set inside (worker thread) fire no :func:`handler`."""
    _sync.active = True
    try:
        yield
    finally:
        _sync.active = False


class Panels:
    """All GUI folders; ``studio`` supplies the state, the worker and file transfers."""

    def __init__(self, server: viser.ViserServer, studio: StudioHost) -> None:
        self.studio = studio
        gui = server.gui
        self.status = gui.add_markdown("**Opening the design...**")
        self.busy = gui.add_markdown("*Working on the design...*", visible=False)
        with gui.add_folder("Details", expand_by_default=False):
            self.details = gui.add_markdown("*Nothing computed yet.*")
        self.frame = gui.add_button("Frame all", icon=viser.Icon.FOCUS_CENTERED,
                                    hint="point the camera at the targets, the motion and the "
                                         "linkage (left of this panel)")
        self.cancel = gui.add_button("Cancel job", icon=viser.Icon.PLAYER_STOP, color="red",
                                     visible=False, hint="stop the running fit, carving or "
                                                         "export (the design is kept)")
        self.rescale = gui.add_button("Rescale", visible=False,
                                      hint="change the design's unit so its size is near 1 "
                                           "(one Undo step)")
        self.view = ViewPanel(gui, studio.state.hidden)
        self.layers = self.view.layers
        self.thickness = self.view.thickness
        with gui.add_folder("Design"):
            self.name = gui.add_text("Name", initial_value="", hint="the design's name (files "
                                     "and downloads are named after it)")
            self.undo = gui.add_button("Undo", icon=viser.Icon.ARROW_BACK_UP,
                                       hint="undo the last edit (a whole drag is one edit)")
            self.redo = gui.add_button("Redo", icon=viser.Icon.ARROW_FORWARD_UP,
                                       hint="redo the edit you last undid")
            self.save = gui.add_button("Save design", icon=viser.Icon.DEVICE_FLOPPY,
                                       hint="download the design file (JSON)")
            self.load = gui.add_upload_button("Load design", icon=viser.Icon.UPLOAD,
                                              mime_type="application/json",
                                              hint="open a design file (JSON) from your disk")
            self.export = gui.add_button("Export result", icon=viser.Icon.DOWNLOAD,
                                         hint="download the solution: motion, six "
                                              "factorizations, nine loops, realization (JSON)")
            self.animation = gui.add_button("Animation (glTF)", icon=viser.Icon.MOVIE,
                                            hint="download the realized loop over one cycle, "
                                                 "turned as the Drive folder's motor and speed "
                                                 "schedule turn it, as an animated .glb for "
                                                 "Blender or a web viewer")
        with gui.add_folder("Targets"):
            self.locks_folder = gui.add_folder("Locks")
            self.locks: list[viser.GuiCheckboxHandle] = []
            self.pose_pick = gui.add_dropdown("Pose", ("S0",), hint="the target pose that "
                                              "Remove pose removes")
            self.add_pose = gui.add_button("Add pose", hint="a new target on the motion, in its "
                                           "largest gap (drag its gizmo to move it)")
            self.remove_pose = gui.add_button("Remove pose", hint="remove the pose picked "
                                              "above (at least four stay)")
        with gui.add_folder("Motion"):
            self.method = gui.add_dropdown(
                "Motion from", tuple(METHOD_NAMES.values()),
                hint="Through 4 poses: the cubic motion through exactly four target poses "
                "(paper Sec. 4.2, 'four-pose'); Fitted to all poses: a cubic motion fitted to "
                "five or more targets (curve evolution, Sec. 4.3, 'fit')")
            self.family = gui.add_dropdown(
                "Motion family", FAMILY_NAMES, hint="four poses admit two one-parameter "
                "families of cubic motions (the paper's solution families 0 and 1, Sec. 4.2); "
                "Motion shape picks one motion in the family")
            self.mu = gui.add_slider(
                "Motion shape", min=-MU_RANGE, max=MU_RANGE, step=0.001,
                initial_value=0.0, hint="which motion of the family: the family parameter "
                "μ (mu) of Sec. 4.2, a number without unit; the range widens to fit")
            self.mu_inf = gui.add_checkbox(
                "Neutral shape", initial_value=True,
                hint="the family's motion at μ = ∞ (mu at infinity, Sec. 4.2)")
            self.criterion = gui.add_dropdown(
                "Best shape means", tuple(CRITERION_NAMES.values()),
                initial_value=CRITERION_NAMES["length"],
                hint="what Find best shape optimizes (the paper's criteria, Sec. 4.2): the "
                "shortest path of the object weighted by its inertia ellipsoid ('length'), "
                "joint axes of the base or end link through the target points ('base-axes', "
                "'end-axes'), closest to the extra poses ('extra-poses'), or the smoothest "
                "motor drive ('smooth-drive')")
            self.best_mu = gui.add_button("Find best shape", hint="scan the family for the "
                                          "motion shape (μ) that is best by the choice above")
        self.evolution = EvolutionPanel(gui, self._evolution, handler)
        with gui.add_folder("Loop"):
            self.loop = gui.add_dropdown(
                "Loop variant", tuple(loop_label(k) for k in range(9)),
                hint="one motion gives nine 6R loops (Sec. 4.3), angle-symmetric or "
                "double-Bennett; the score is the singularity measure S (Sec. 4.4): higher "
                "stays farther from a jamming, singular pose")
        self.realization = RealizationPanel(gui, studio, handler)
        self.real = self.realization.inputs
        self.effector = EffectorPanel(gui, studio, handler)
        with gui.add_folder("Animation"):
            self.u = gui.add_slider("Cycle position", min=0.0, max=1.0, step=0.001,
                                    initial_value=0.0,
                                    hint="0 .. 1 runs once through the whole motion (the "
                                         "paper's parameter t, from t = ∞ back to ∞)")
            self.play = gui.add_checkbox("Play", initial_value=False,
                                         hint="animate the linkage through its cycle")
            self.speed = gui.add_slider("Speed", min=0.01, max=1.0, step=0.01,
                                        initial_value=0.1, hint="cycles per second")
        self._connect()

    # --- handlers ---------------------------------------------------------------------------
    def _connect(self) -> None:
        s = self.studio
        st = s.state
        self.undo.on_click(handler(lambda _: self._history(st.undo)))
        self.redo.on_click(handler(lambda _: self._history(st.redo)))
        self.save.on_click(handler(s.download_design))
        self.export.on_click(handler(s.download_export))
        self.animation.on_click(handler(s.download_animation))
        self.load.on_upload(handler(s.upload_design))
        self.name.on_update(handler(lambda _: self._edit("name", name=self.name.value)))
        self.rescale.on_click(handler(lambda _: self._rescale()))
        self.add_pose.on_click(handler(lambda _: self._add_pose()))
        self.remove_pose.on_click(handler(lambda _: self._remove_pose()))
        self.method.on_update(handler(lambda _: self._motion(
            method=value_of(METHOD_NAMES, self.method.value))))
        self.family.on_update(handler(lambda _: self._motion(
            family=FAMILY_NAMES.index(self.family.value))))
        self.mu.on_update(handler(lambda _: self._set_mu()))
        self.mu_inf.on_update(handler(lambda _: self._motion(
            mu=None if self.mu_inf.value else float(self.mu.value), criterion=None)))
        self.best_mu.on_click(handler(lambda _: self._motion(
            criterion=value_of(CRITERION_NAMES, self.criterion.value))))
        self.loop.on_update(handler(lambda _: self._edit(loop=loop_of_label(self.loop.value))))
        self.u.on_update(handler(lambda _: self._set_u(self.u.value)))
        self.play.on_update(handler(lambda _: setattr(st, "playing", self.play.value)))
        self.speed.on_update(handler(lambda _: setattr(st, "speed", self.speed.value)))
        self.thickness.on_update(handler(lambda _: self._thickness(self.thickness.value)))
        for name, box in self.layers.items():
            box.on_update(handler(lambda _, name=name, box=box: self._layer(name, box.value)))

    def _history(self, step: Any) -> None:
        if step():
            self.studio.request(FULL, sync=True)

    def _edit(self, merge: str | None = None, **changes: Any) -> None:
        self.studio.state.edit(lambda d: dataclasses.replace(d, **changes), merge)
        self.studio.request(FULL)

    def _motion(self, merge: str | None = None, **changes: Any) -> None:
        self.studio.state.edit(lambda d: dataclasses.replace(
            d, motion=dataclasses.replace(d.motion, **changes)), merge)
        self.studio.request(FULL)

    def _set_mu(self) -> None:
        with writing_back():  # a slider move leaves "mu at infinity"
            self.mu_inf.value = False
        self._motion(merge="mu", mu=float(self.mu.value), criterion=None)

    def _evolution(self, key: str, value: Any) -> None:
        options = {**self.studio.state.design.evolution, key: value}
        try:  # refuse settings the design file could not hold (they would break the autosave)
            evolution_settings(options)
        except (TypeError, ValueError) as exc:
            self.studio.notify("Fitting", str(exc), error=True)
            self.studio.request(FRAME, sync=True)
            return
        self.studio.state.edit(lambda d: dataclasses.replace(
            d, evolution={**d.evolution, key: value}), key)
        self.studio.request(FULL)

    def _add_pose(self) -> None:
        self.studio.state.add_pose(pose_in_gap(self.studio.state.design, self.studio.solution))
        self.studio.request(FULL, sync=True)

    def _rescale(self) -> None:
        """*Rescale*: the design in a unit that brings its size near 1 (one undo step)."""
        factor = unit_factor(design_scale(self.studio.state.design))
        self.studio.state.edit(lambda d: rescaled(d, factor))
        self.studio.reframe()
        self.studio.request(FULL, sync=True)
        self.studio.notify("Design rescaled", f"every length x {factor:g}", cause="scale")

    def _remove_pose(self) -> None:
        if self.studio.state.remove_pose(int(self.pose_pick.value[1:])):
            self.studio.request(FULL, sync=True)
        else:
            self.studio.notify("Remove pose", "a design needs at least four target poses",
                               error=True)

    def _set_lock(self, i: int, handle: viser.GuiCheckboxHandle) -> None:
        if self.studio.state.set_locked(i, handle.value):
            self.studio.request(FULL, sync=True)
        else:
            self.studio.notify("Lock", "at least one target must stay free", error=True)
            self.studio.request(FRAME, sync=True)  # unchanged design: only write the box back

    def _layer(self, name: str, show: bool) -> None:
        hidden = self.studio.state.hidden
        (hidden.discard if show else hidden.add)(name)
        self.studio.request(FRAME)

    def _thickness(self, value: float) -> None:
        self.studio.state.thickness = float(value)
        self.studio.request(FRAME)

    def _set_u(self, u: float) -> None:
        self.studio.state.u = float(u)
        self.studio.request(FRAME)

    # --- writing values back ----------------------------------------------------------------
    def sync(self, design: Design) -> None:
        """Show ``design``'s settings in the widgets (no handler fires)."""
        with writing_back():
            self.name.value = design.name
            n = len(design.poses)
            if len(self.locks) != n:
                for h in self.locks:
                    h.remove()
                gui = self.studio.server.gui
                with self.locks_folder:
                    self.locks = [gui.add_checkbox(f"Lock S{i}", initial_value=False,
                                                   hint="a locked target cannot be dragged")
                                  for i in range(n)]
                for i, h in enumerate(self.locks):
                    h.on_update(handler(lambda _, i=i, h=h: self._set_lock(i, h)))
                self.pose_pick.options = tuple(f"S{i}" for i in range(n))
            for i, h in enumerate(self.locks):
                h.value = i in design.locked
            m = design.motion
            self.method.value = METHOD_NAMES[m.method]
            self.family.value = FAMILY_NAMES[m.family]
            self._show_mu(m.mu)
            if m.criterion is not None:
                self.criterion.value = CRITERION_NAMES[m.criterion]
            self.loop.value = self.loop.options[design.loop]
            self.evolution.sync(design)
            self.effector.sync(design)
            self.realization.sync(design)

    def show_status(self, text: str, detail: str | None = None) -> None:
        """The status sentence and, if given, the Details text."""
        self.status.content = f"**{text}**"
        if detail is not None:
            self.details.content = detail

    def show_solution(self, sol: Any) -> None:
        """Loop picker labels with singularity values/status, and the mu actually used."""
        with writing_back():
            status = singularity.loop_status(sol.singularity)
            opts = tuple(loop_label(k, float(sol.singularity[k]), status[k]) for k in range(9))
            self.loop.options = opts
            self.loop.value = opts[sol.design.loop]
            self.evolution.show(sol.fit)
            self.effector.show(sol)
            if sol.design.motion.criterion is not None:  # the mu the criterion chose
                self._show_mu(sol.mu)

    def _show_mu(self, mu: float | None) -> None:
        """The mu controls for ``mu`` (inside :func:`writing_back`)."""
        half = mu_range(mu)
        if self.mu.max != half:
            self.mu.min, self.mu.max = -half, half
        self.mu_inf.value = mu is None
        if mu is not None:
            self.mu.value = round(float(mu), 3)

    def set_u(self, u: float) -> None:
        with writing_back():
            self.u.value = u

