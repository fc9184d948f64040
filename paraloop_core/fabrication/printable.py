"""Printable by default: size, radii, grounding and bed fit chosen by the program.

:func:`export_printable` sizes the parts from the realization's certified pair bounds
(:mod:`sizing`), builds, exports and verifies them (:func:`export.export_parts`), and then

* grounding: the column is tried as the caller asks (default: the first base axis that
  works); where no column is collision-free the parts are exported without one and the
  report says so (``warnings``), rather than failing;
* bed fit: each part's oriented bounding box must fit the printer's bed in some orientation;
  if one does not and the size was chosen automatically, the size shrinks by the worst
  part's ratio (never below the profile's minimum) and the parts are rebuilt.

When no size meets every constraint the :class:`FabricationError` names the conflict and the
best reachable size.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import export, sizing
from paraloop_core.fabrication.export import ExportResult
from paraloop_core.fabrication.parts import PartSpec

#: Rebuilds allowed to shrink an automatically sized assembly onto the bed.
_FIT_ROUNDS = 3


def part_extents(result: ExportResult) -> np.ndarray:
    """Sorted oriented-bounding-box extents ``(6, 3)`` (mm) of the exported parts."""
    return np.array([p["obb_extents_mm"] for p in result.report["parts"]])


def export_printable(joint_factors: np.ndarray, points: np.ndarray, radius: float,
                     lim: sizing.Limits, *, printer: sizing.Printer = sizing.PRINTERS["generic"],
                     size_mm: float | None = None, print_in_place: bool = False,
                     ground: bool = True, **options) -> ExportResult:
    """Parts of a realized loop sized for ``printer`` (module docstring); ``lim`` from
    :func:`sizing.limits` of the same realization, ``options`` as :func:`export.export_parts`.
    The report gains ``sizing`` (size, radii, minimum size and its binding constraint, the
    printer, bed fit) and ``warnings``."""
    auto = size_mm is None
    sz = sizing.choose_size(lim, printer, size_mm)
    warnings: list[str] = []
    for _ in range(_FIT_ROUNDS + 1):
        spec = PartSpec(size_mm=sz.size_mm, clearance_mm=printer.clearance_mm,
                        rho_mm=sz.bar_radius_mm, boss_radius_mm=sz.boss_radius_mm,
                        pin_radius_mm=sz.pin_radius_mm, print_in_place=print_in_place)
        # bed fit from the built parts first; the (costly) verification only for the last
        result = _export(joint_factors, points, radius, spec, ground, warnings,
                         {**options, "verify": False})
        fit = sizing.fits_bed(part_extents(result), printer)
        if fit.all() or not auto:
            result = _export(joint_factors, points, radius, spec, ground, [], options)
            break
        ratio = float(np.min(np.sort(printer.bed_mm)[None] / part_extents(result)[~fit]))
        smaller = sz.size_mm * min(ratio, 0.99)
        if smaller < sz.min_size_mm:
            raise FabricationError(
                f"no size fits printer {printer.name!r} (bed {_bed(printer)} mm): the "
                f"{sz.binding} needs at least {np.ceil(sz.min_size_mm):.0f} mm, where the "
                f"largest part is {part_extents(result).max():.0f} mm long; use a larger "
                "printer (--printer / --bed), thinner walls or a thinner pin", "bad-parameters")
        sz = sizing.choose_size(lim, printer, smaller)
    warnings += sizing.notch_warnings(points, sz, printer)
    if not fit.all():
        warnings.append(f"parts {np.flatnonzero(~fit).tolist()} do not fit the bed "
                        f"{_bed(printer)} mm at the requested {sz.size_mm:.0f} mm")
    result.report["sizing"] = {
        "size_mm": sz.size_mm, "chosen": "auto" if auto else "requested",
        "bar_radius_mm": sz.bar_radius_mm, "boss_radius_mm": sz.boss_radius_mm,
        "pin_radius_mm": sz.pin_radius_mm, "min_size_mm": sz.min_size_mm,
        "binding_constraint": sz.binding, "printer": printer.name, "bed_mm": printer.bed_mm,
        "wall_mm": printer.wall_mm, "fits_bed": fit.tolist()}
    result.report["warnings"] = warnings
    return _with_report(result)


def _export(joint_factors, points, radius, spec, ground, warnings, options) -> ExportResult:
    try:
        return export.export_parts(joint_factors, points, radius, spec=spec, ground=ground,
                                   **options)
    except FabricationError as exc:
        if not ground or exc.reason != "grounding":
            raise
        warnings.append(f"exported without a grounding column: {exc}")
    return export.export_parts(joint_factors, points, radius, spec=spec, ground=False,
                               **options)


def _bed(printer: sizing.Printer) -> str:
    return " x ".join(f"{v:g}" for v in printer.bed_mm)


def _with_report(result: ExportResult) -> ExportResult:
    """``result`` with ``report.json`` rewritten from the (amended) report."""
    files = [(n, b) for n, b in result.files if n != "report.json"]
    return replace(result, files=files + [("report.json", export.report_json(result.report))])
