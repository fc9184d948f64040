"""Which realization to print: the candidates sized, the best first.

:func:`choose` takes candidate realizations (lazily: each is a new, equally certified search,
made by the caller, which knows the design), sizes each (:func:`sizing.plan`: the largest size
whose parts fit the bed, the thickest bars the certificate allows, joints with real hardware)
and ranks them: fewest flaws (a bar cut across, bars thinner than the floors, a loop near a
singular pose: :func:`singularity.loop_status`), the width and length/width aims met, then the
largest size, then the thickest thinnest bar; the first candidate is the design's own loop.
When none can be sized, the refusal says why and what would work (:mod:`remedy`).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from paraloop_core.errors import FabricationError, RealizationError
from paraloop_core.fabrication import bed, flat, joints, profiles, remedy, rows, sizing
from paraloop_core.fabrication.profiles import Options
from paraloop_core.fabrication.progress import Progress
from paraloop_core.linkage import loops
from paraloop_core.realization.certified import Realization

#: Most candidate realizations sized before the best so far is taken.
MAX_CANDIDATES = 16
#: Sized candidates after which the choice is made even when none meets the aims (each more
#: costs a realization and a sizing; the best of three is rarely beaten later).
ENOUGH_SIZED = 3
#: More candidates sized past :data:`ENOUGH_SIZED` while every one sized would print a link
#: over supports by its own layouts (:func:`_lifted_by_plan`).
FLAT_SEARCH = 2


@dataclass(frozen=True)
class Candidate:
    """A realization to try: what it is (``label``), the design ``loop`` index, and ``make()``
    returning ``(Realization, end-effector realization or None)`` or raising
    :class:`RealizationError`; ``near_singular``: the loop's cycle passes close to a
    singular configuration (:func:`singularity.loop_status`)."""

    label: str
    loop: int
    make: Callable[[], tuple[Realization, object | None]]
    near_singular: bool = False


def cut(layouts: Iterable[joints.Joint]) -> bool:
    """Whether a joint of ``layouts`` cuts a bar across its centre line
    (:func:`joints.cut_sides`)."""
    return any(any(j.cut) for j in layouts)


def _score(cand: Candidate, plan: sizing.Plan) -> tuple:
    # a bar cut across its core or thinner than the floors is what a maker sees first, and
    # a loop that may switch branches or jam near a singular pose what it does first; then
    # the level, the joints, the size
    kinds = profiles.AUTO_JOINTS
    rank = -kinds.index(plan.kind) if plan.kind in kinds else 0
    flaws = int(cut(plan.layouts)) + int(plan.level >= 3) + int(cand.near_singular)
    return (-flaws, -plan.level, rank, round(plan.size_mm, 0), float(plan.radii.min()))


def _plan(real: Realization, opts: Options, size_mm: float | None = None,
          ee: object | None = None) -> sizing.Plan:
    """:func:`sizing.plan` with the options' joints (``auto``: :data:`profiles.AUTO_JOINTS`
    in turn, the first that reaches the best level); ``size_mm`` overrides the options'."""
    kinds = profiles.AUTO_JOINTS if opts.joints == "auto" else (opts.joints,)
    extra = None if ee is None else {3: ee.effector.vertices}
    best, errors = None, []
    for kind in kinds:
        try:
            p = sizing.plan(real, opts.printer, opts.material, kind, opts.rod,
                            size_mm=size_mm or opts.size_mm,
                            fit=lambda q: bed.predicted_fit(q, real.points, opts.printer,
                                                             extra), ee=ee)
        except FabricationError as exc:
            errors.append(exc)
            continue
        if best is None or p.level < best.level:
            best = p
        if best.level <= 1:
            break
    if best is None:
        if len(errors) > 1 and all(isinstance(e, sizing.NoRoomError) for e in errors):
            # the first names its hardware: every kind tried had no room, say so
            raise sizing.NoRoomError(str(errors[0]).replace(
                f"({kinds[0]})", f"({', '.join(kinds[:-1])} or {kinds[-1]})"), "bad-parameters")
        raise errors[0]
    return best


def choose(candidates: Iterable[Candidate], opts: Options, progress: Progress | None = None
           ) -> tuple[list[tuple[Candidate, Realization, object | None, sizing.Plan]],
                      list[str], list[remedy.Refused]]:
    """The sized candidates, best first (module docstring), what was tried and the
    realizations made but without room at this bed (:data:`remedy.Refused`). Raises
    :class:`FabricationError` naming every failure when none can be sized (with what would
    work: :func:`remedy.refusal`), and for joints printed in place on a loop whose axes do
    not allow it (:func:`joints.in_place_refusal`)."""
    tried, sized, lifted, roomless = [], [], [], []
    for n, cand in enumerate(itertools.islice(candidates, MAX_CANDIDATES)):
        if progress is not None:
            progress(n / MAX_CANDIDATES, f"sizing {cand.label}")
        try:
            real, ee = cand.make()
            if opts.joints == "print-in-place":
                why = joints.in_place_refusal(loops.factor_axes(real.joint_factors))
                raise FabricationError(why or "print-in-place is not built by paraloop",
                                       "bad-parameters")
            plan = _plan(real, opts, ee=ee)
        except (RealizationError, FabricationError) as exc:
            if opts.joints == "print-in-place":
                raise
            tried.append(f"{cand.label}: {exc}")
            if isinstance(exc, sizing.NoRoomError):  # made, but no room at this bed
                roomless.append((cand.label, real, ee))
            continue
        tried.append(f"{cand.label}: {plan.size_mm:.0f} mm, bars "
                     f"{plan.radii.min() * sizing.FLATS:.1f} mm wide or more"
                     + ("" if plan.aims_met else f" ({sizing.LEVELS[plan.level]})"))
        sized.append((cand, real, ee, plan))
        lifted.append(_lifted_by_plan(real, plan, opts))
        enough = sum(c[3].aims_met and not cut(c[3].layouts) and not c[0].near_singular
                     for c in sized) >= \
            (1 if opts.size_mm is not None else 2) \
            or len(sized) >= ENOUGH_SIZED
        # two that meet the aims (the design's loop first) are enough to choose from, unless
        # each would print a link over supports: then a few more
        if enough and (not all(lifted) or len(sized) >= ENOUGH_SIZED + FLAT_SEARCH):
            break
    if not sized:
        # the hardware is the same at every size, the room between the links grows with it
        raise FabricationError(remedy.refusal(tried, roomless, opts, plan_of),
                               "bad-parameters")
    return sorted(sized, key=lambda c: _score(c[0], c[3]), reverse=True), tried, roomless


def plan_of(real: Realization, opts: Options, ee: object | None) -> sizing.Plan:
    """:func:`_plan` as :data:`remedy.Sizer` (the remedies size realizations again)."""
    return _plan(real, opts, ee=ee)


def _lifted_by_plan(real: Realization, plan: sizing.Plan, opts: Options) -> bool:
    """Whether some link of ``plan`` has no print flat (:func:`flat.lies_flat`) with the
    sizing's own joint layouts (the grounding rod's bore may still take more)."""
    need = sizing.flat_radii(rows.bounds_of(real), plan.scale, plan.layouts,
                             opts.printer.wall_mm)
    return not all(flat.lies_flat(s) for s in (plan.radii - need) * sizing.APOTHEM)
