"""Studio controls of the motion evolution (method 'fit', paper Sec. 4.3).

The values live in ``Design.evolution`` (the JSON-native settings of
:class:`paraloop_core.motion.evolution_stages.EvolutionSettings`); handlers only edit the state.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import viser

from paraloop_core.design import Design
from paraloop_core.motion.evolution import evolution_settings

#: (key, label, kind, default, hint); kind is 'int', 'float', 'bool' or a tuple of choices.
FIELDS = (
    ("init", "Start from", ("four-pose", "random"), "random",
     "how each attempt starts: four-pose interpolates four of the targets, random draws "
     "spherical starts (the paper's initial guess, eq. 9)"),
    ("starts", "Attempts", "int", 20, "how many starts are tried; the best fit wins "
     "(multi-start)"),
    ("seed", "Random seed", "int", 0, "the seed of the random starts (the same seed gives the "
     "same fit)"),
    ("w0", "Orientation weight", "float", 3.0, "how much the targets' orientations count "
     "against their positions at first, at least 1 (the paper's w0, Sec. 4.3)"),
    ("q", "Weight easing", "float", 0.1, "how fast the orientation weight is eased off per "
     "middle-stage step, a fraction (the paper's q, Sec. 4.3)"),
    ("max_iterations", "Max steps per attempt", "int", 100, "the most fitting steps one "
     "attempt may take"),
    ("ordered", "Visit poses in order", "bool", True, "the motion visits the targets in their "
     "order S0, S1, ..."),
    ("free_reference", "Treat all poses alike", "bool", False,
     "in the final stage S0 is no longer hit exactly, which is fairer to the other targets "
     "(the paper's free reference frame)"),
    ("loop_fix", "Avoid loops in the path", "bool", False, "the modified procedure against "
     "loops in the motion's path (the paper's loop fix, Fig. 17)"),
)


class EvolutionPanel:
    """The 'Evolution' folder; ``edit(key, value)`` changes one setting of the design."""

    def __init__(self, gui: viser.GuiApi, edit: Callable[[str, Any], None],
                 guard: Callable[[Callable[[Any], None]], Callable[[Any], None]]) -> None:
        self.handles: dict[str, Any] = {}
        with gui.add_folder("Fitting (motion fitted to all poses)", expand_by_default=False):
            for key, label, kind, default, hint in FIELDS:
                if isinstance(kind, tuple):
                    h = gui.add_dropdown(label, kind, initial_value=default, hint=hint)
                elif kind == "bool":
                    h = gui.add_checkbox(label, initial_value=default, hint=hint)
                else:
                    step = 1 if kind == "int" else 0.05
                    h = gui.add_number(label, initial_value=default, step=step, hint=hint)
                h.on_update(guard(lambda _, key=key, kind=kind, h=h: edit(
                    key, int(h.value) if kind == "int" else h.value)))
                self.handles[key] = h
            self.report = gui.add_markdown("Fit: none yet (choose Motion from: Fitted to all "
                                           "poses, with five or more poses).")

    def sync(self, design: Design) -> None:
        """Show the design's settings (defaults where the design says nothing)."""
        settings = evolution_settings(design.evolution)
        for key, h in self.handles.items():
            h.value = getattr(settings, key)

    def show(self, fit: Any) -> None:
        """Summarize a :class:`paraloop_core.motion.evolution.FitResult` (or None)."""
        if fit is None:
            return
        worst = float(fit.distances.max()) if len(fit.distances) else 0.0
        self.report.content = (
            f"Fit: cost {fit.cost:.3g} ({fit.status}), start {fit.winning_start} of "
            f"{fit.starts_tried}, worst target distance {worst:.3g}"
            + (f", loops at gaps {list(fit.loops)}" if fit.loops else ""))
