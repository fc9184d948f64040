"""What the studio's export buttons download, and the fabrication settings as core options.

*Export result* downloads the result JSON (:func:`export_files`); *Animation* the realized
loop over one cycle as an animated glTF (:func:`animation_file`, as ``paraloop animate``);
*Export all* one zip ``paraloop-<design>.zip`` (:func:`export_zip`) with that JSON and, when
the design has a realization, the printed loop of :func:`printed.export` as ``paraloop
export`` writes it (parts, plates, assembly, guide, ``report.json``, the printed loop's
``result.json`` and its animation). Size 0 is automatic, as in the CLI.
"""

from __future__ import annotations

import io
import zipfile
from collections.abc import Callable
from typing import Any

import numpy as np

from app.state import FabSettings
from paraloop_core import pipeline, printed
from paraloop_core.design import DriveSettings
from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import animate, printable, profiles, sizing, spaces
from paraloop_core.linkage import drive_plan
from paraloop_core.linkage.drive import TWO_PI
from paraloop_core.result import json_text

#: Carving orders offered by the panel: target links first to last, each carved by the later.
ORDER_PRESETS = {"base first": (0, 1, 2, 3, 4, 5), "end first": (3, 2, 4, 1, 5, 0)}
CUSTOM = "custom"


def slug(name: str) -> str:
    """A file-name-safe version of a design name."""
    s = "".join(c if c.isalnum() or c in "-_" else "-" for c in name)[:60].strip("-")
    return s or "design"


def export_files(solution: pipeline.Solution) -> list[tuple[str, bytes]]:
    """Files ``(name, content)`` exported for a solved design: the result JSON."""
    result = json_text(pipeline.result_to_dict(solution))
    return [("paraloop-result.json", result.encode("utf-8"))]


def animation_keyframes(real: Any, drive: DriveSettings, frames: int
                        ) -> tuple[np.ndarray, float, str]:
    """``(t (frames,), cycle time s, what drives it)`` for an animation of the realization
    ``real`` as the design's ``drive`` plan turns it (:func:`drive_plan.plan_drive`, base
    link resting): its motor with the speed schedule, or at constant speed when no schedule
    meets the drive's limits."""
    plan = drive_plan.plan_drive(real.joint_factors, drive)
    if plan.schedule is not None:
        t = animate.scheduled_parameters(real.joint_factors, plan.schedule, frames)
        return t, plan.cycle_time_s, f"motor joint {plan.motor} with its speed schedule"
    theta = np.linspace(0.0, TWO_PI, frames)
    return (animate.motor_parameters(real.joint_factors, plan.motor, theta), plan.cycle_time_s,
            f"motor joint {plan.motor} at constant speed (no schedule meets the limits)")


def animation_file(solution: pipeline.Solution, frames: int = 240) -> tuple[str, bytes]:
    """``(name, .glb bytes)``: the realized loop over one cycle as the design's drive turns
    it (:func:`animation_keyframes`, :mod:`animate`); raises ValueError when the design has no
    collision-free realization."""
    real = solution.realization
    if real is None:
        raise ValueError("the design has no collision-free realization to animate")
    t, seconds, _ = animation_keyframes(real, solution.design.drive, frames)
    glb = animate.animated_glb(real.joint_factors, real.points, real.radius, frames=frames,
                               seconds=seconds, t=t)
    return f"{slug(solution.design.name)}-cycle.glb", glb


def parse_order(text: str) -> list[tuple[int, int]]:
    """``'0-1, 0-2, ...'`` (target-source) -> pairs; every pair of the six links exactly once.
    Raises ValueError naming the problem."""
    pairs = []
    for item in filter(None, (s.strip() for s in text.replace(";", ",").split(","))):
        a, sep, b = item.partition("-")
        if not sep or not a.strip().isdigit() or not b.strip().isdigit():
            raise ValueError(f"'{item}': expected target-source, e.g. 0-3")
        pair = (int(a), int(b))
        if not (0 <= pair[0] < 6 and 0 <= pair[1] < 6) or pair[0] == pair[1]:
            raise ValueError(f"'{item}': links are 0..5 and differ")
        pairs.append(pair)
    seen = {frozenset(p) for p in pairs}
    if len(seen) != len(pairs):
        raise ValueError("a pair of links is listed twice")
    if len(seen) != 15:
        raise ValueError(f"list all 15 pairs of the six links (got {len(seen)}), so every "
                         "two design spaces are carved against each other")
    return pairs


def carve_order(fab: FabSettings) -> list[tuple[int, int]]:
    """The ``(target, source)`` pairs of the chosen preset or of the custom text."""
    if fab.order == CUSTOM:
        return parse_order(fab.custom_order)
    links = ORDER_PRESETS[fab.order]
    return [(a, b) for k, a in enumerate(links) for b in links[k + 1:]]


def printer_of(fab: FabSettings) -> profiles.Printer:
    """The panel's printer profile with its build volume (when given) and clearance."""
    bed = profiles.parse_bed(fab.bed) if fab.bed.strip() else None
    return profiles.printer(fab.printer, bed, fab.clearance_mm)


def options_of(fab: FabSettings) -> printable.Options:
    """The export options of the panel's settings (size 0: automatic)."""
    return printable.Options(printer=printer_of(fab), size_mm=fab.size_mm or None,
                             ground=fab.ground, ground_link=fab.ground_link,
                             joints="print-in-place" if fab.print_in_place else "auto")


def size_of(sol: pipeline.Solution, fab: FabSettings) -> float:
    """The size (mm) the panel's settings print at: the panel's, else the expected automatic
    size (the parts' final size is the export's)."""
    return print_size(sol.realization, fab)


def print_size(real: Any, fab: FabSettings) -> float:
    """:func:`size_of` for a realization."""
    return fab.size_mm if fab.size_mm > 0 else printed.bed_size(real.points, printer_of(fab))


def print_estimate(real: Any, fab: FabSettings) -> tuple[float, float | None]:
    """``(size, bar width)`` (mm) the on-screen realization would print at with the export's
    automatic joints (M3 screws, M2 where M3 does not fit): :func:`print_size` and the
    thinnest bar the sizing gives it there (None when no joints fit: *Export all* then
    realizes the loop again with roomier joints, as it may anyway, so the exported parts can
    differ)."""
    size = print_size(real, fab)
    for kind in profiles.AUTO_JOINTS:
        try:
            plan = sizing.plan(real, printer_of(fab), profiles.MATERIALS["pla"], kind,
                               profiles.DEFAULT_ROD, size_mm=size)
        except FabricationError:
            continue
        return size, float(plan.radii.min() * sizing.FLATS)
    return size, None


def carve_spaces(sol: pipeline.Solution, fab: FabSettings,
                 progress: Callable[[float, str], None] | None = None) -> tuple[Any, list]:
    """Carve and mesh the realization's design spaces with the panel's settings; an
    end-effector (``Solution.end_effector``) is part of link 3."""
    real = sol.realization
    scale = size_of(sol, fab) / float(np.max(np.ptp(real.points, axis=0)))
    radius = (fab.space_radius_mm / scale if fab.space_radius_mm > 0
              else float(np.median(real.design_space_radii)))
    return spaces.carve_design_spaces(real.joint_factors, real.points, real.radius, radius,
                                      scale=scale, resolution=fab.resolution or None,
                                      order=carve_order(fab), effector=sol.end_effector,
                                      progress=progress)


def export_zip(solution: pipeline.Solution, fab: FabSettings,
               progress: Callable[[float, str], None] | None = None,
               ) -> tuple[str, bytes, dict | None]:
    """``(zip name, zip bytes, report or None)``: the result JSON plus, when the design has a
    realization, the printed loop's files as ``paraloop export`` writes them. Raises
    :class:`FabricationError` on bad settings."""
    files = export_files(solution)
    report = None
    if solution.realization is not None:
        parts, report, _ = printed.export(solution, options_of(fab), progress=progress)
        files += parts
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in files:
            zf.writestr(name, data)
    return f"paraloop-{slug(solution.design.name)}.zip", buf.getvalue(), report
