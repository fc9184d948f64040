"""The studio's status-line texts: the realization note and the unit warning."""

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
