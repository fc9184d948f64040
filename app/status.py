"""The studio's status: one sentence in a designer's words (:func:`headline`, at most
:data:`HEADLINE_MAX` characters, no symbols, no e-notation) and the technical details folded
below it (:func:`details`: clearances, certified radii, work budgets, counts); the unit
warning.

Target poses are named as their labels name them (``S0``, ``S1``, ...); sizes in mm are the
printed ones (``app.sizes``).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

import numpy as np

from app.scene import design_scale
from app.sizes import PrintSizes, Size
from app.state import FabSettings
from paraloop_core import pipeline
from paraloop_core.design import Design
from paraloop_core.errors import FitError, InterpolationError, NonGenericMotionError
from paraloop_core.realization import radii

#: Characteristic lengths (design units) outside which the studio warns about the unit.
USUAL_SCALE = (1e-2, 1e3)
#: Longest status sentence (characters).
HEADLINE_MAX = 160


def plain(x: float, digits: int = 3) -> str:
    """``x`` with ``digits`` significant digits, never in e-notation (0.00012, 12000)."""
    return np.format_float_positional(float(x), precision=digits, unique=False,
                                      fractional=False, trim="-")


def unit_factor(scale: float) -> float:
    """Power of ten that brings a characteristic length ``scale`` near 1."""
    return float(10.0 ** -np.round(np.log10(scale)))


def scale_warning(design: Design) -> str:
    """A warning when the design's size is far from 1 unit (else '')."""
    scale = design_scale(design)
    if USUAL_SCALE[0] <= scale <= USUAL_SCALE[1]:
        return ""
    return (f"The targets span {plain(scale)} units: any unit works, but sizes near 1 read "
            f"best (press Rescale for x {plain(unit_factor(scale))}).")


def _pose(last_moved: int | None) -> str:
    return "the pose" if last_moved is None else f"S{last_moved}"


def _fit(text: str, extra: str) -> str:
    """``text`` with ``extra`` appended when both fit in :data:`HEADLINE_MAX`."""
    return text + extra if extra and len(text + extra) <= HEADLINE_MAX else text


def headline(sol: pipeline.Solution, *, full: bool, moved: bool, searching: bool,
             refining: bool, last_moved: int | None, size: Size | None) -> str:
    """The status sentence after drawing ``sol``: a full update or a drag preview
    (``moved``: it shows the last realization moved along), ``searching`` the full
    realization search follows, ``refining`` a multi-start fit follows, ``last_moved`` the
    target the last edit dragged, ``size`` the printed (size, bar thickness) in mm, or why it
    cannot be printed at the chosen size, or None (not measured yet)."""
    real, enabled = sol.realization, sol.design.realization.enabled
    if not full:
        text = (f"Moving {_pose(last_moved)} - the loop follows and is checked for collisions "
                "when you let go" if moved else
                f"Moving {_pose(last_moved)} - let go to search for a collision-free loop")
    elif searching:
        text = "Searching for a collision-free loop..."
    elif real is None and enabled:
        text = ("No collision-free loop for this design: undo the last change, pick another "
                "loop variant, or allow thinner bars" if last_moved is None else
                f"No collision-free loop for this pose: move {_pose(last_moved)} back, or allow "
                "thinner bars")
    elif real is None:
        text = "Motion ready - collision-free bars are switched off (Realization)"
    elif isinstance(size, tuple) and size[1] is not None:
        text = (f"Collision-free loop found - {size[0]:.0f} mm across, {plain(size[1], 2)} mm "
                "bars when printed")
    elif isinstance(size, tuple):
        text = f"Collision-free loop found - about {size[0]:.0f} mm across when printed"
    elif isinstance(size, str):
        text = f"Collision-free loop found - {size}"
    else:
        text = "Collision-free loop found - measuring it for print..."
    if refining:
        text = _fit(text, "; refining the motion fit...")
    return _fit(text, " (unusual size: see Rescale)" if scale_warning(sol.design) else "")


def error_headline(exc: Exception, last_moved: int | None, shown: bool) -> str:
    """The status sentence when the design cannot be solved (``shown``: the last valid
    design stays on screen)."""
    pose = _pose(last_moved)
    reason = getattr(exc, "reason", "")
    if isinstance(exc, InterpolationError) and reason == "coincident":
        text = f"Two target poses coincide: move {pose} away from the others"
    elif isinstance(exc, InterpolationError):
        text = (f"No motion of this kind passes through these poses: move {pose} a little, or "
                "try the other motion family")
    elif isinstance(exc, NonGenericMotionError):
        text = f"This motion cannot be built as a loop: move {pose} a little, or undo"
    elif isinstance(exc, FitError) and reason == "too-few-poses":
        text = "Fitting needs at least five poses: add a pose, or make the motion through 4 poses"
    elif isinstance(exc, FitError):
        text = f"The motion could not be fitted: move {pose} back, or change the fitting settings"
    else:
        text = "This design cannot be solved: undo the last change (see Details)"
    return _fit(text, " - the last good design is shown" if shown else "")


def realization_note(sol: pipeline.Solution) -> str:
    """The realization of the selected loop in numbers (Details)."""
    real = sol.realization
    if real is None:
        return "" if sol.design.realization.enabled else "Realization: off."
    rad = radii.certified_radii(real.pairs, real.pair_lower, real.radius)
    return (f"Realized loop {sol.design.loop}: bar radius {real.radius:.3g}, "
            f"min clearance {real.min_clearance:.3g}; certified thickest: every bar and pin "
            f"{rad.uniform:.3g}, per bar " + ", ".join(f"{r:.3g}" for r in rad.per_bar) + ".")


def details(sol: pipeline.Solution, *, full: bool, ms: float, note: str, ghost: bool,
            moved: bool, refine_starts: int | None, searching: bool = False) -> str:
    """The technical details after drawing ``sol``: update kind and time, the realization
    (radius, clearance, certified radii) or ``note`` why there is none, ``ghost`` the last
    realized linkage shown faint, ``refine_starts`` the starts of the multi-start fit that
    follows (None: none), ``searching`` the full search follows a quick one that missed."""
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
    kind = "full update" if full else "preview"
    warning = scale_warning(sol.design)
    return f"{kind.capitalize()} in {ms:.0f} ms. {note}" + (f"\n\n{warning}" if warning else "")


class StatusLine:
    """The status sentence and Details on screen (``show(text, detail)``, the panels'
    :meth:`~app.panels.design.Panels.show_status`); a solution's sentence is rewritten when
    its printed size (:class:`app.sizes.PrintSizes`, for the settings ``fab()``) is known."""

    def __init__(self, show: Callable[..., None], fab: Callable[[], FabSettings]) -> None:
        self._show, self._fab = show, fab
        self._lock = threading.Lock()
        self._args: dict | None = None  # headline arguments of the solution on screen
        self._text = ""
        self.sizes = PrintSizes(self.refresh)

    def set(self, text: str, detail: str | None = None) -> None:
        """Show ``text`` (and ``detail`` in Details, if given)."""
        with self._lock:
            self._args, self._text = None, text
            self._show(text, detail)

    def solution(self, detail: str, **args: Any) -> str:
        """Show the :func:`headline` of ``args`` (without ``size``) and ``detail``; the text."""
        with self._lock:
            self._args = args
            self._text = headline(**args, size=self._size(args))
            self._show(self._text, detail)
            return self._text

    def refresh(self) -> None:
        """Rewrite the solution's sentence if its printed size became known (or the
        Fabrication settings changed it)."""
        with self._lock:
            if self._args is None:
                return
            text = headline(**self._args, size=self._size(self._args))
            if text != self._text:
                self._text = text
                self._show(text)

    def _size(self, args: dict) -> Size | None:
        real = args["sol"].realization
        return None if real is None or not args["full"] else self.sizes.get(real, self._fab())

    def close(self) -> None:
        self.sizes.close()
