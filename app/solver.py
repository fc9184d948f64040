"""The studio's solves: full updates cached (undo/redo is instant) and warm-started from the
last drag preview's pattern and the last realized solution; drag previews uncertified."""

from __future__ import annotations

import dataclasses
import json
from collections import OrderedDict
from collections.abc import Callable

from app.state import absolute_mesh
from paraloop_core import design as design_mod
from paraloop_core import pipeline
from paraloop_core.design import Design
from paraloop_core.errors import RealizationError

CACHE_SIZE = 16
#: Work units of the release's realization search (0.1 - 0.2 s on the examples): when the warm
#: start does not clear and this does not suffice, the full search (thinner bars, the whole
#: budget) runs as a job (:meth:`Solver.solve` with ``quick`` False).
QUICK_WORK = 2500


def incomplete(sol: pipeline.Solution) -> bool:
    """Whether ``sol`` came from a quick search that found no realization (the full search
    has not run yet)."""
    return bool((sol.realization_report or {}).get("incomplete"))


class Solver:
    """``solve(design, full, current)`` for the worker thread only."""

    def __init__(self) -> None:
        self._cache: OrderedDict[str, tuple[pipeline.Solution, str]] = OrderedDict()
        self.realized: pipeline.Solution | None = None  # warm start of the next realization
        self.preview: pipeline.WarmPreview | None = None  # the last preview's linkage
        self._preview_fit: tuple[str, object] | None = None  # (design key, its 1-start fit)

    @staticmethod
    def _key(design: Design) -> str:
        data = design_mod.design_to_dict(absolute_mesh(design))  # a mesh path per file
        del data["name"], data["locked"]  # neither changes the solution
        drive = data.pop("drive")  # nor the drive, but for the smooth-drive criterion's motor
        if design.motion.criterion == "smooth-drive":
            data["motor"] = drive["motor"]
        return json.dumps(data, sort_keys=True)

    def quick_fit(self, design: Design) -> tuple[pipeline.Solution, str] | None:
        """A ``fit`` design's full update from the one-start fit its last drag preview made
        (no evolution: the realization, warm-started, is certified as always), or None when
        no preview was made for exactly this design. The multi-start fit follows
        (:meth:`solve` with ``full``) and replaces it only if it fits better."""
        if self._preview_fit is None or self._preview_fit[0] != self._key(design):
            return None
        return self._full(design, dict(fit=self._preview_fit[1]), quick=True)

    def _full(self, design: Design, extra: dict, quick: bool = False,
              check: Callable[[], None] | None = None) -> tuple[pipeline.Solution, str]:
        """A full update: the last preview's pattern and the last realization's are tried
        first (certified like any answer), then the search (``quick``: :data:`QUICK_WORK`
        units on the design's own loop and bars; ``check`` may raise to stop it)."""
        pattern, self.preview = (None if self.preview is None else self.preview.pattern), None
        try:
            sol = pipeline.solve(design, other_loops=False, hint=self.realized,
                                 pattern=pattern, quick_work=QUICK_WORK if quick else None,
                                 check=check, **extra)
            report = sol.realization_report or {}
            note = (f"No realization: {report.get('reason')}"
                    if report.get("status") == "not_found" and not incomplete(sol) else "")
            return sol, note
        except RealizationError as exc:
            return pipeline.solve(design, realize=False, **extra), f"No realization: {exc}"

    def solve(self, design: Design, full: bool, current: pipeline.Solution | None,
              progress: Callable[[float, str], None] | None = None, *, quick: bool = False,
              check: Callable[[], None] | None = None) -> tuple[pipeline.Solution, str]:
        """``(solution, note)`` of ``design``; the note says why there is no realization.

        A preview (``full`` False) reuses ``current``'s mu instead of re-running a criterion's
        scan, refits a ``fit`` design from the fit on screen (one start), and moves the last
        realization along when the exact minima clear it (:attr:`preview`,
        :func:`pipeline.warm_preview`; certified only by the full update on release). The
        studio keeps the user's loop: fallbacks only thin the bars. A full update's ``quick``
        search that finds nothing is not cached (:func:`incomplete`): the full search follows."""
        hint = self.realized
        key = self._key(design)
        if not full:
            m = design.motion
            if m.criterion is not None and current is not None:
                motion = dataclasses.replace(m, criterion=None, mu=current.mu)
                design = dataclasses.replace(design, motion=motion)
            if m.method == "fit":  # a drag refits one start, from the fit on screen
                design = dataclasses.replace(design, evolution={**design.evolution, "starts": 1})
            sol = pipeline.solve(design, realize=False, hint=current)
            self.preview = None if hint is None else pipeline.warm_preview(sol, hint)
            self._preview_fit = None if sol.fit is None else (key, sol.fit)
            return sol, ""
        if key in self._cache:
            self.preview = None  # the drag's pattern belongs to this release only
        else:
            sol, note = self._full(design, dict(progress=progress), quick, check)
            if incomplete(sol):
                return sol, note
            self.remember(design, sol, note)
        self._cache.move_to_end(key)
        sol, note = self._cache[key]
        return dataclasses.replace(sol, design=design), note

    def complete(self, design: Design, fit: object, check: Callable[[], None] | None = None
                 ) -> tuple[pipeline.Solution, str]:
        """The full update of a ``fit`` design with the motion ``fit`` (its drag's) and the
        full realization search (after a quick one missed)."""
        return self._full(design, dict(fit=fit), check=check)

    def remember(self, design: Design, sol: pipeline.Solution, note: str) -> None:
        """Make ``(sol, note)`` the full update of ``design`` (undo/redo return it); a quick
        search that missed (:func:`incomplete`) is never kept."""
        if incomplete(sol):
            raise ValueError("an incomplete realization search cannot be cached")
        self._cache[self._key(design)] = (sol, note)
        while len(self._cache) > CACHE_SIZE:
            self._cache.popitem(last=False)
