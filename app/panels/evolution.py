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
    ("init", "Initial guess", ("four-pose", "random"), "random",
     "four-pose: interpolate four of the targets; random: spherical starts (eq. 9)"),
    ("starts", "Starts", "int", 20, "number of starts (multi-start)"),
    ("seed", "Seed", "int", 0, "seed of the random starts"),
    ("w0", "Orientation weight w0", "float", 3.0, "initial-stage weight (>= 1)"),
    ("q", "Weight reduction q", "float", 0.1, "fraction per middle-stage iteration"),
    ("max_iterations", "Max iterations", "int", 100, "cap per start"),
    ("ordered", "Ordered targets", "bool", True, "visit the targets in the given order"),
    ("free_reference", "Free reference frame", "bool", False,
     "final stage: S_0 no longer hit exactly, fairer to all targets"),
    ("loop_fix", "Loop fix", "bool", False, "modified procedure against loops (Fig. 17)"),
)


class EvolutionPanel:
    """The 'Evolution' folder; ``edit(key, value)`` changes one setting of the design."""

    def __init__(self, gui: viser.GuiApi, edit: Callable[[str, Any], None],
                 guard: Callable[[Callable[[Any], None]], Callable[[Any], None]]) -> None:
        self.handles: dict[str, Any] = {}
        with gui.add_folder("Evolution (method fit)", expand_by_default=False):
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
            self.report = gui.add_markdown("Fit: none yet (choose method 'fit' with >= 5 poses).")

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
