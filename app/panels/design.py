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
from app.scene import FACTOR_COLOR_NAMES, LAYERS
from app.worker import FRAME, FULL
from paraloop_core.algebra import factor
from paraloop_core.design import CRITERIA, METHODS, Design
from paraloop_core.linkage import loops
from paraloop_core.motion.evolution import evolution_settings

if TYPE_CHECKING:
    from app.host import StudioHost

_sync = threading.local()
LABELS = "ABC"


def order_name(j: int) -> str:
    """Norm order of factorization ``j``, e.g. ``'BAC'``."""
    return "".join(LABELS[k] for k in factor.NORM_ORDERS[j])


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


def loop_status(singularity: np.ndarray) -> list[str]:
    """Status word per loop from its singularity measure, relative to the largest of the nine."""
    s = np.asarray(singularity, float)
    ref = max(float(s.max()), 1e-300)
    return ["singular" if v <= 1e-9 * ref else "near-singular" if v <= 1e-3 * ref
            else "ok" for v in s]


#: Smallest half-range of the mu slider; it widens to show any mu of the design.
MU_RANGE = 5.0


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

    def __init__(self, server: viser.ViserServer, studio: StudioHost,
) -> None:
        self.studio = studio
        gui = server.gui
        self.status = gui.add_markdown("**Status:** starting")
        self.frame = gui.add_button("Frame all", icon=viser.Icon.FOCUS_CENTERED,
                                    hint="point the camera at the targets, the motion and the "
                                         "linkage (left of this panel)")
        self.cancel = gui.add_button("Cancel job", icon=viser.Icon.PLAYER_STOP, color="red",
                                     visible=False, hint="stop the running fit, carving or "
                                                         "export (the design is kept)")
        self.rescale = gui.add_button("Rescale", visible=False,
                                      hint="change the design's unit so its size is near 1 "
                                           "(one Undo step)")
        with gui.add_folder("Design"):
            self.name = gui.add_text("Name", initial_value="", hint="the design's name (files "
                                     "and downloads are named after it)")
            self.undo = gui.add_button("Undo", icon=viser.Icon.ARROW_BACK_UP,
                                       hint="undo the last edit (a whole drag is one edit)")
            self.redo = gui.add_button("Redo", icon=viser.Icon.ARROW_FORWARD_UP)
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
            self.remove_pose = gui.add_button("Remove pose", hint="at least four stay")
        with gui.add_folder("Motion"):
            self.method = gui.add_dropdown(
                "Motion from", METHODS, hint="four-pose: the cubic motion through four target "
                "poses (paper Sec. 4.2); fit: a cubic motion fitted to five or more targets by "
                "curve evolution (Sec. 4.3)")
            self.family = gui.add_dropdown(
                "Solution family", ("0", "1"), hint="four poses admit two one-parameter "
                "families of cubic motions (Sec. 4.2); mu picks one motion in the family")
            self.mu = gui.add_slider(
                "Family parameter mu", min=-MU_RANGE, max=MU_RANGE, step=0.001,
                initial_value=0.0, hint="the free parameter of the family (a number, no unit; "
                "Sec. 4.2); the range widens to fit")
            self.mu_inf = gui.add_checkbox("mu at infinity", initial_value=True,
                                           hint="the family's motion at mu = infinity")
            self.criterion = gui.add_dropdown(
                "Choose mu by", CRITERIA, initial_value="length",
                hint="base-axes / end-axes: joint axes through the target points; length: "
                "shortest path of the object, weighted by its inertia ellipsoid; extra-poses: "
                "closest to the extra poses (Sec. 4.2)")
            self.best_mu = gui.add_button("Find best mu", hint="scan the family for the mu "
                                          "that is best by the criterion above")
        self.evolution = EvolutionPanel(gui, self._evolution, handler)
        with gui.add_folder("Loop"):
            self.loop = gui.add_dropdown(
                "6R loop", tuple(loop_label(k) for k in range(9)),
                hint="the nine 6R loops of the motion (Sec. 4.3): angle-symmetric or "
                "double-Bennett; score = singularity measure (Sec. 4.4), higher stays farther "
                "from a jamming, singular pose")
            legend = ", ".join(f"{c} {order_name(j)}" for j, c in enumerate(FACTOR_COLOR_NAMES))
            gui.add_markdown(f"Axes of the six factorizations: {legend}.")
        self.real: dict[str, Any] = {}
        with gui.add_folder("Realization"):
            r = self.real
            r["enabled"] = gui.add_checkbox(
                "Find collision-free bars", initial_value=True,
                hint="search bars on the loop's axes that never collide over the whole motion "
                     "(Sec. 5.1, exact for the continuous cycle)")
            r["p"] = gui.add_number("Shift steps (p)", initial_value=10.0, min=1e-3, step=0.5,
                                    hint="bar ends move along the axes in steps of the loop "
                                         "length / p (Sec. 5.1)")
            r["d_fraction"] = gui.add_number(
                "Joint spacing (x loop length)", initial_value=0.01, min=1e-6, step=0.005,
                hint="d, the distance between the two bar ends on one axis, as a fraction of "
                     "the initial polyline's length (used when the value below is 0)")
            r["rho_fraction"] = gui.add_number(
                "Bar radius (x joint spacing)", initial_value=0.25, min=1e-6, step=0.05,
                hint="rho as a fraction of d (used when the value below is 0)")
            r["d"] = gui.add_number("Joint spacing d (units, 0 = auto)", initial_value=0.0,
                                    min=0.0, step=0.01, hint="in design units")
            r["rho"] = gui.add_number("Bar radius rho (units, 0 = auto)", initial_value=0.0,
                                      min=0.0, step=0.01, hint="in design units")
            r["fixed"] = gui.add_text("Held bar ends", initial_value="",
                                      hint="vertex=offset pairs in design units along the "
                                           "vertex's axis, e.g. 0=0.1, 3=-0.2")
        self.effector = EffectorPanel(gui, studio, handler)
        with gui.add_folder("Animation"):
            self.u = gui.add_slider("Cycle position", min=0.0, max=1.0, step=0.001,
                                    initial_value=0.0,
                                    hint="0 .. 1 runs once through the whole motion")
            self.play = gui.add_checkbox("Play", initial_value=False,
                                         hint="animate the linkage through its cycle")
            self.speed = gui.add_slider("Speed", min=0.01, max=1.0, step=0.01,
                                        initial_value=0.1, hint="cycles per second")
        with gui.add_folder("View", expand_by_default=False):
            self.layers = {name: gui.add_checkbox(name, initial_value=True) for name in LAYERS}
            self.thickness = gui.add_slider("Bar thickness", min=1.0, max=10.0, step=0.5,
                                            initial_value=1.0, hint="x the true bar radius")
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
        self.add_pose.on_click(handler(lambda _: self._add_pose()))
        self.remove_pose.on_click(handler(lambda _: self._remove_pose()))
        self.method.on_update(handler(lambda _: self._motion(method=self.method.value)))
        self.family.on_update(handler(lambda _: self._motion(family=int(self.family.value))))
        self.mu.on_update(handler(lambda _: self._set_mu()))
        self.mu_inf.on_update(handler(lambda _: self._motion(
            mu=None if self.mu_inf.value else float(self.mu.value), criterion=None)))
        self.best_mu.on_click(handler(lambda _: self._motion(criterion=self.criterion.value)))
        self.loop.on_update(handler(lambda _: self._edit(loop=loop_of_label(self.loop.value))))
        for key, handle in self.real.items():
            handle.on_update(handler(lambda _, key=key: self._realization(key)))
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
            self.studio.notify("Evolution", str(exc), error=True)
            self.studio.request(FRAME, sync=True)
            return
        self.studio.state.edit(lambda d: dataclasses.replace(
            d, evolution={**d.evolution, key: value}), key)
        self.studio.request(FULL)

    def _realization(self, key: str) -> None:
        h = self.real[key]
        if key == "fixed":
            try:
                value: Any = parse_fixed(h.value)
            except ValueError as exc:
                self.studio.notify("Fixed vertices", str(exc), error=True)
                return
        elif key in ("d", "rho"):
            value = float(h.value) or None
        else:
            value = h.value
        self.studio.state.edit(lambda d: dataclasses.replace(
            d, realization=dataclasses.replace(d.realization, **{key: value})), key)
        self.studio.request(FULL)

    def _add_pose(self) -> None:
        self.studio.state.add_pose(self.studio.new_pose())
        self.studio.request(FULL, sync=True)

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
            self.method.value, self.family.value = m.method, str(m.family)
            self._show_mu(m.mu)
            if m.criterion is not None:
                self.criterion.value = m.criterion
            self.loop.value = self.loop.options[design.loop]
            self.evolution.sync(design)
            self.effector.sync(design)
            r = design.realization
            for key, h in self.real.items():
                if key == "fixed":
                    h.value = ", ".join(f"{k}={v:g}" for k, v in sorted(r.fixed.items()))
                elif key in ("d", "rho"):
                    h.value = getattr(r, key) or 0.0
                else:
                    h.value = getattr(r, key)

    def show_solution(self, sol: Any) -> None:
        """Loop picker labels with singularity values/status, and the mu actually used."""
        with writing_back():
            status = loop_status(sol.singularity)
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


def parse_fixed(text: str) -> dict[int, float]:
    """``'0=0.1, 3=-0.2'`` -> ``{0: 0.1, 3: -0.2}``; raises ValueError on bad input."""
    out: dict[int, float] = {}
    for item in filter(None, (s.strip() for s in text.split(","))):
        key, sep, val = item.partition("=")
        if not sep or not key.strip().isdigit() or not 0 <= int(key) < 6:
            raise ValueError(f"'{item}': expected vertex=offset with vertex 0..5")
        try:
            out[int(key)] = float(val)
        except ValueError:
            raise ValueError(f"'{item}': offset is not a number") from None
        if not np.isfinite(out[int(key)]):
            raise ValueError(f"'{item}': offset must be finite")
    return out

