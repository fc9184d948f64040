"""What would work when no realization of a design prints: other joints, a larger print, or
none.

The joints' hardware (screw, nut, dowel) keeps its size while the room between the links grows
with the print. A realization refused for room (:class:`sizing.NoRoomError`: at every size the
bed allows, its bosses and hardware do not fit where the certificate keeps the links apart)
may have it in a larger print. :func:`larger_print` sizes those realizations again, on beds
up to :data:`FACTORS` times the printer's (or at that many times the size the maker fixed),
and names the smallest that gives one of them room; or says that none does, so that a larger
print would not help. Where the maker chose the joints (``--joints printed-pin`` or ``m4``,
whose heads, caps and nuts reach farther past the bosses), :func:`other_joints` first sizes
them with the default joints (:data:`profiles.AUTO_JOINTS`) on the same print and names
those where they have room: the maker keeps the bed. The sizing predicts the parts from the
certified rows (joints, bosses, bars); the export on that bed builds and verifies them as
always.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication.profiles import Options
from paraloop_core.fabrication.sizing import FLATS, LEVELS
from paraloop_core.realization.certified import Realization

#: Multiples of the printer's bed (or of the maker's size) tried, smallest first.
FACTORS = (1.25, 1.5, 2.0, 3.0)
#: Refused realizations sized again (the first ones tried: the design's loop, the roomiest).
MAX_TRIED = 8

#: ``(label, realization, end-effector realization or None)`` of a candidate refused for room.
Refused = tuple[str, Realization, object | None]
#: The exporter's sizing of one realization under some options (raises FabricationError).
Sizer = Callable[[Realization, Options, object | None], object]


def refusal(tried: Sequence[str], refused: Sequence[Refused], opts: Options,
            size: Sizer) -> str:
    """The message of an export that prints no realization: why (how many of those ``tried``
    had no room), what would work (:func:`larger_print`), then every try: the why and the
    remedy first, where a one-line error shows them."""
    where = f"at {opts.size_mm:.0f} mm" if opts.size_mm is not None else \
        "at every size tried that the bed allows"
    n, r = len(tried), len(refused)
    why = f"{r} of {n} tried leave{'s' * (r == 1)} the joints no room {where}" \
        if refused else f"none of the {n} realizations tried was found and sized"
    if refused and r < n:
        why += f", {n - r} were not found or not sized"
    return (f"no realization of this design can be printed with real joints ({why})."
            f"{other_joints(refused, opts, size)}{larger_print(refused, opts, size)} Tried: "
            + "; ".join(tried) + ".")


def other_joints(refused: Sequence[Refused], opts: Options, size: Sizer) -> str:
    """The sentence naming the default joints (``--joints auto``) where the maker chose
    others and a realization of ``refused`` has room with them on the same print; "" when
    the maker kept the default or they have no room either."""
    if opts.joints == "auto" or not refused:
        return ""
    auto = replace(opts, joints="auto")
    for label, real, ee in list(refused)[:MAX_TRIED]:
        try:
            plan: Any = size(real, auto, ee)
        except FabricationError:
            continue
        return (f" With the default joints (--joints auto: {plan.kind.upper()} screws and "
                f"lock nuts instead of {_JOINT_WORDS.get(opts.joints, opts.joints)}) it prints "
                f"on this bed: {label} has room for them at {plan.size_mm:.0f} mm.")
    return ""


#: The maker's joints in words (:func:`other_joints`).
_JOINT_WORDS = {"printed-pin": "printed pins and caps", "m2": "M2 screws",
                "m3": "M3 screws", "m4": "M4 screws"}


def larger_print(refused: Sequence[Refused], opts: Options, size: Sizer) -> str:
    """The sentence the refusal ends with: the smallest larger print (a bed, or a size when
    ``opts.size_mm`` is fixed) on which ``size`` finds room for a realization of
    ``refused``, or that none up to ``FACTORS[-1]`` times has it. ``refused`` empty: ""."""
    if not refused:
        return ""
    found = _smallest_print(list(refused)[:MAX_TRIED], opts, FACTORS, size)
    if found is None:
        what = "a size" if opts.size_mm is not None else "a bed"
        return (f" A larger print would not help: at {what} {FACTORS[-1]:g} times as large no "
                "realization tried has room for its joints either. What would work: a design "
                "whose links pass farther apart (other poses, family or mu).")
    label, scaled, plan = found
    return _words(label, scaled, float(plan.size_mm))


def _smallest_print(cands: Sequence[Refused], opts: Options, factors: Sequence[float],
                    size: Sizer, ok: Callable[[Any], bool] = lambda plan: True
                    ) -> tuple[str, Options, Any] | None:
    """``(label, options, plan)`` of the smallest print of ``factors`` times ``opts``' on
    which ``size`` gives one of ``cands`` (in order) a plan ``ok`` takes, or None. The
    largest print first: the realizations without one even there are left out."""
    def plan_on(c: Refused, scaled: Options) -> Any:
        try:
            plan = size(c[1], scaled, c[2])
        except FabricationError:
            return None
        return plan if ok(plan) else None

    largest = _scaled(opts, factors[-1])
    kept = [(c, p) for c in cands if (p := plan_on(c, largest)) is not None]
    for f in factors[:-1]:
        scaled = _scaled(opts, f)
        for c, _ in kept:
            plan = plan_on(c, scaled)
            if plan is not None:
                return c[0], scaled, plan
    return (kept[0][0][0], largest, kept[0][1]) if kept else None


#: Multiples of the bed tried for bars within the floors (:func:`stronger_print`), and how
#: many of the realizations sized at the bed are sized again there.
STRONGER_FACTORS, STRONGER_TRIED = (1.25, 1.5), 4


def stronger_print(sized: Sequence[Refused], opts: Options, size: Sizer) -> dict:
    """Where the printed bars are thinner than the floors (:data:`sizing.LEVELS`' thin bars):
    the smallest bed of :data:`STRONGER_FACTORS` on which ``size`` gives one of the
    realizations ``sized`` (the printed one first, then the others sized, then those without
    room at this bed; the first :data:`STRONGER_TRIED`) bars within the floors, as the
    report's ``sizing.larger_print`` (``bed_mm``, ``realization``, ``size_mm``,
    ``bar_width_mm``, ``length_per_width``, ``sentence``); or ``{"bed_mm": None,
    "sentence": ...}`` saying none reaches it; with a size the maker fixed, ``{}``."""
    if opts.size_mm is not None or not sized:
        return {}
    found = _smallest_print(list(sized)[:STRONGER_TRIED], opts, STRONGER_FACTORS, size,
                            lambda plan: plan.level < LEVELS.index("thin bars"))
    if found is not None:
        label, scaled, plan = found
        width = plan.radii * FLATS
        lw = float(max(plan.deflection.lengths / width))
        x, y, z = scaled.printer.bed_mm
        return {"bed_mm": [x, y, z], "realization": label, "size_mm": plan.size_mm,
                "bar_width_mm": float(width.min()), "length_per_width": lw,
                "sentence": f"what would work: a bed of at least {x:.0f} x {y:.0f} x {z:.0f} "
                            f"mm (--bed {x:.0f},{y:.0f},{z:.0f}), where {label} has bars "
                            f"{width.min():.1f} mm wide or more and at most {lw:.0f} times as "
                            f"long as wide at {plan.size_mm:.0f} mm"}
    return {"bed_mm": None, "sentence": f"no bed up to {STRONGER_FACTORS[-1]:g} times this "
            "one gives the realizations tried bars within those; what would work: a design "
            "whose links pass farther apart (other poses, family or mu)"}


def _words(label: str, scaled: Options, size_mm: float) -> str:
    if scaled.size_mm is not None:
        return (f" What would work: --size-mm {scaled.size_mm:.0f}, if the bed takes it (a "
                f"larger print leaves the joints' hardware more room: {label} has it there), "
                "or no --size-mm (the largest size the bed takes); or a design whose links "
                "pass farther apart.")
    x, y, z = scaled.printer.bed_mm
    return (f" What would work: a bed of at least {x:.0f} x {y:.0f} x {z:.0f} mm (--bed "
            f"{x:.0f},{y:.0f},{z:.0f}), where {label} has room for its joints at "
            f"{size_mm:.0f} mm; or a design whose links pass farther apart.")


def _scaled(opts: Options, f: float) -> Options:
    """``opts`` with the bed (or the fixed size) ``f`` times as large, whole millimetres up."""
    if opts.size_mm is not None:
        return replace(opts, size_mm=float(math.ceil(opts.size_mm * f)))
    bed = tuple(float(math.ceil(v * f)) for v in opts.printer.bed_mm)
    return replace(opts, printer=replace(opts.printer, name=f"{opts.printer.name} x{f:g}",
                                         bed_mm=bed))
