"""The View folder (the linkage, drawn thicker on request) and the Construction folder: the
paper's construction aids, hidden when the studio starts (``app.scene.HIDDEN_AT_START``).

The checkboxes are keyed by layer name (``app.scene.LINKAGE`` and ``CONSTRUCTION``); the
design panel connects their handlers (they only edit ``state.hidden``)."""

from __future__ import annotations

from typing import Any

import viser

from app.scene import CONSTRUCTION, FACTOR_COLOR_NAMES, LINKAGE, PARTS
from paraloop_core.algebra import factor

#: Tooltips of the construction layers (the paper's terms and sections).
HINTS = {
    "Trajectory": "the path of the moving frame's origin over the whole cycle of the motion",
    "Moving frames": "the moving frame at 24 points of the cycle and at the animated one "
                     "(the paper's C(t), Sec. 4)",
    "Inertia ellipsoid": "the design's inertia ellipsoid on the moving frame: the metric that "
                         "weighs positions against rotations (eq. 8, Sec. 4.2)",
    "Factorization axes": "the rotation axes of the motion's six factorizations at the home "
                          "pose (t = ∞), coloured as the paper's Fig. 5 (Sec. 3)",
    "Loop axes": "the six joint axes of the selected loop at the animated pose (Sec. 4.3)",
    "Design spaces": "the carved design spaces (Fabrication: Carve design spaces), moving with "
                     "their links: the room each link may fill (Sec. 5.2)",
}


def order_name(j: int) -> str:
    """Norm order of factorization ``j``, e.g. ``'BAC'``."""
    return "".join("ABC"[k] for k in factor.NORM_ORDERS[j])


class ViewPanel:
    """The View and Construction folders; ``hidden``: the layers hidden at start."""

    def __init__(self, gui: viser.GuiApi, hidden: set[str]) -> None:
        with gui.add_folder("View"):
            linkage = gui.add_checkbox(
                "Show the linkage", initial_value=LINKAGE not in hidden,
                hint="the loop as an object moving with the cycle: its printed parts, or "
                     "each link a solid bar of its true radius with hubs at its joints")
            parts = gui.add_checkbox(
                "Show printed parts", initial_value=PARTS not in hidden,
                hint="the parts Export all would print (links with their thickness, screws, "
                     "the base), built in the background a moment after each change; off, "
                     "or while they are being built, solid bars stand in for them")
            self.thickness = gui.add_slider(
                "Draw bars thicker", min=1.0, max=10.0, step=0.5, initial_value=1.0,
                hint="display only: bars and hubs drawn this many times their true radius "
                     "(1 = true size; the design and its exports are unchanged)")
        self.layers: dict[str, Any] = {LINKAGE: linkage, PARTS: parts}
        with gui.add_folder("Construction", expand_by_default=False):
            gui.add_markdown("The paper's construction aids (off at start).")
            for name in CONSTRUCTION:
                self.layers[name] = gui.add_checkbox(name, initial_value=name not in hidden,
                                                     hint=HINTS[name])
            legend = ", ".join(f"{c} {order_name(j)}" for j, c in enumerate(FACTOR_COLOR_NAMES))
            gui.add_markdown(f"Factorization axes: {legend}.")

    def show(self, name: str, hidden: set[str]) -> None:
        """Switch layer ``name`` on and tick its box (inside ``writing_back``)."""
        hidden.discard(name)
        self.layers[name].value = True
