"""The studio's status line: its text, the realization note and the unit warning."""

from __future__ import annotations

import numpy as np

from app.scene import design_scale
from paraloop_core import pipeline
from paraloop_core.design import Design
from paraloop_core.realization import radii

#: Characteristic lengths (design units) outside which the studio warns about the unit.
USUAL_SCALE = (1e-2, 1e3)


def unit_factor(scale: float) -> float:
    """Power of ten that brings a characteristic length ``scale`` near 1."""
    return float(10.0 ** -np.round(np.log10(scale)))


def scale_warning(design: Design) -> str:
    """A status warning when the design's size is far from 1 unit (else '')."""
    scale = design_scale(design)
    if USUAL_SCALE[0] <= scale <= USUAL_SCALE[1]:
        return ""
    return (f" ⚠ The targets span {scale:.3g} units: paraloop works in any unit, but sizes "
            f"near 1 read best (press Rescale for x {unit_factor(scale):g}).")


def realization_note(sol: pipeline.Solution) -> str:
    """One status line about the realization of the selected loop."""
    real = sol.realization
    if real is None:
        return "" if sol.design.realization.enabled else "Realization: off."
    rad = radii.certified_radii(real.pairs, real.pair_lower, real.radius)
    return (f"Realized loop {sol.design.loop}: bar radius {real.radius:.3g}, "
            f"min clearance {real.min_clearance:.3g}; certified thickest: every bar and pin "
            f"{rad.uniform:.3g}, per bar " + ", ".join(f"{r:.3g}" for r in rad.per_bar) + ".")


def status_line(sol: pipeline.Solution, *, full: bool, ms: float, note: str, ghost: bool,
                moved: bool, refine_starts: int | None, searching: bool = False) -> str:
    """The status after drawing ``sol``: a full update or a preview (``moved``: it shows the
    last realization moved along), ``note`` why there is no realization ('' if there is one),
    ``ghost`` the last realized linkage shown faint, ``refine_starts`` the starts of the
    multi-start fit that follows a quick one (None: none follows), ``searching`` the full
    realization search follows a quick one that found nothing."""
    if full and not note:
        note = realization_note(sol)
    elif note and ghost:
        note += " The last realized linkage is shown faint."
    if not full and moved:
        note = "Linkage: the last realization moved along (or a new shift pattern found), " \
               "its minima checked exactly; certified collision-free on release."
    if refine_starts:
        note += (f" Motion: the drag's one-start fit; refining it with {refine_starts} starts "
                 "in the background.")
    if searching:
        note += (" Realization: none found by the quick search; the full search (deeper "
                 "shifts, thinner bars) is running (an edit or Cancel job stops it).")
    # "ok" only when there is a loop to show (or none was asked for)
    word = "⚠ no collision-free realization" if full and sol.realization is None and \
        sol.design.realization.enabled else "ok"
    if searching:
        word = "⚠ searching for a collision-free realization"
    kind = "full update" if full else "preview"
    return f"**Status:** {word} ({kind} {ms:.0f} ms). {note}{scale_warning(sol.design)}"
