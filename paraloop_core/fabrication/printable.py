"""Printable by default: size, radii, grounding and bed fit chosen by the program.

:func:`export_printable` sizes the parts from the realization's certified pair bounds
(:mod:`sizing`), builds, exports and verifies them (:func:`export.export_parts`), and then

* grounding: the column is tried as the caller asks (default: the first base axis that
  works); where no column is collision-free the parts are exported without one and the
  report says so (``warnings``), rather than failing;
* bed fit: each part's oriented bounding box must fit the printer's bed in some orientation;
  if one does not and the size was chosen automatically, the size shrinks by the worst
  part's ratio (never below the profile's minimum) and the parts are rebuilt; the
  verification over the cycle runs once, on the parts of the size kept.

When no size meets every constraint the :class:`FabricationError` names the conflict and the
best reachable size.

:func:`roomier` comes first: the realization's certified clearances are relative to the loop,
so a thin realization (the default offset d is 1 % of the polyline) needs a large print. If its
parts are predicted not to fit the bed at its smallest printable size, the loop is realized
again with d and rho times :data:`ROOMIER`, then the design's other loops are tried (each a
new, equally certified search) and the first predicted to fit is used.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from paraloop_core.design import DriveSettings
from paraloop_core.errors import FabricationError, RealizationError
from paraloop_core.fabrication import drive_mass, export, guide, sizing, thickness
from paraloop_core.fabrication.export import ExportResult
from paraloop_core.fabrication.parts import Assembly, PartSpec
from paraloop_core.realization import realize
from paraloop_core.realization.certified import Realization

#: Rebuilds allowed to shrink an automatically sized assembly onto the bed, and to grow it
#: by :data:`_GROW` where a link falls apart (a bar notched through at a joint).
_FIT_ROUNDS = 3
_GROW_ROUNDS, _GROW = 3, 1.2
#: Factors on d and rho of the realizations :func:`roomier` tries, and the work budget of each
#: (``realize.Search.work``).
ROOMIER = (2.0, 4.0, 8.0)
ROOMIER_WORK = 60_000
#: Predicted bed fit (:func:`predicted_fit`) a realization must reach to be kept as it is:
#: the prediction leaves out the joint zones' rounding and the column.
FIT_MARGIN = 1.05


def min_size_mm(real: Realization, printer: sizing.Printer) -> float:
    """Smallest size (mm) at which the parts of ``real`` meet ``printer``'s profile."""
    return sizing.choose_size(sizing.realization_limits(real), printer).min_size_mm


def predicted_fit(real: Realization, printer: sizing.Printer) -> tuple[float, float]:
    """``(size, fit)``: the smallest size (mm) meeting the profile and, at that size, the
    smallest :func:`sizing.fit_factor` of the predicted parts (>= 1: every part fits the bed).
    A part is predicted as link i's bar with half of each pin, a box along the principal axes
    of ``mid(E_{i-1}, S_i), S_i, E_i, mid(E_i, S_{i+1})`` grown by the boss radius; an
    estimate for choosing a realization (columns and carved bodies are not in it), the built
    parts are measured again."""
    lim = sizing.realization_limits(real)
    sz = sizing.choose_size(lim, printer, sizing.choose_size(lim, printer).min_size_mm)
    pts = np.asarray(real.points, float) * sz.scale
    s, e = pts[0::2], pts[1::2]
    link = np.stack([(np.roll(e, 1, axis=0) + s) / 2, s, e, (e + np.roll(s, -1, axis=0)) / 2], 1)
    centred = link - link.mean(axis=1, keepdims=True)
    _, _, vt = np.linalg.svd(centred)  # (6, 3, 3) principal axes per part
    ext = np.ptp(np.einsum("pnk,pjk->pnj", centred, vt), axis=1) + 2 * sz.boss_radius_mm
    return sz.size_mm, float(sizing.fit_factor(ext, printer).min())


def roomier(real: Realization, printer: sizing.Printer, fixed: dict[int, float] | None = None,
            alternatives: Mapping[int, np.ndarray] | None = None, replace_it: bool = False
            ) -> tuple[Realization, str | None]:
    """``real`` if its parts are predicted to fit the bed at the smallest size meeting the
    profile (:func:`predicted_fit`, with :data:`FIT_MARGIN`), else the first realization that
    is: the loop with d and rho times each of :data:`ROOMIER`, then each loop of
    ``alternatives`` (design loop index -> joint factors ``(6, 8)``) with its default d
    and rho times 1, then times the smaller :data:`ROOMIER`; if none is, the best predicted
    one. Every
    candidate is a new, equally certified search (budget :data:`ROOMIER_WORK`); the note says
    what was done. ``fixed`` vertices as in the design. ``replace_it``: ``real`` itself cannot
    be used (its parts fall apart), so any candidate is better than it."""
    need, fit = predicted_fit(real, printer)
    if fit >= FIT_MARGIN and not replace_it:
        return real, None
    best, best_size, best_fit, best_what = real, need, -np.inf if replace_it else fit, ""
    tried = []
    plan = [(real.joint_factors, f, f"d and rho x{f:g}", True) for f in ROOMIER]
    plan += [(jf, f, f"loop {n}" + ("" if f == 1 else f", d and rho x{f:g}"), False)
             for f in (1.0, *ROOMIER[:-1]) for n, jf in (alternatives or {}).items()]
    for jf, f, what, same in plan:
        base = {"d": real.separation * f, "rho": real.radius * f} if same else \
            {"d_fraction": 0.01 * f, "rho_fraction": 0.25}
        try:
            r = realize.realize(jf, p=real.p, fixed=fixed, budget=ROOMIER_WORK, **base)
        except RealizationError as exc:
            tried.append(f"{what}: {exc.reason}")
            continue
        size, fit = predicted_fit(r, printer)
        tried.append(f"{what}: {size:.0f} mm, fit {fit:.2f}")
        if fit > best_fit:
            best, best_size, best_fit, best_what = r, size, fit, what
        if fit >= FIT_MARGIN:
            break
    if best is real:
        return real, (f"the realization's parts are predicted not to fit the bed at its "
                      f"smallest printable size {need:.0f} mm, and no roomier one was found "
                      f"({'; '.join(tried)})")
    return best, (f"realized again for printing with {best_what} (the design's realization "
                  f"needs {need:.0f} mm, this one {best_size:.0f} mm, "
                  f"predicted bed fit {best_fit:.2f}); certified like the first")


def part_extents(result: ExportResult) -> np.ndarray:
    """Sorted oriented-bounding-box extents ``(6, 3)`` (mm) of the exported parts."""
    return np.array([p["obb_extents_mm"] for p in result.report["parts"]])


def export_printable(realization: Realization, *,
                     printer: sizing.Printer = sizing.PRINTERS["generic"],
                     size_mm: float | None = None, print_in_place: bool = False,
                     ground: bool = True, samples: int = 720,
                     fixed: dict[int, float] | None = None,
                     alternatives: Mapping[int, np.ndarray] | None = None,
                     drive: DriveSettings | None = None,
                     progress: export.Progress | None = None, **options) -> ExportResult:
    """Parts of ``realization`` sized for ``printer`` (module docstring); ``options`` as
    :func:`export.export_parts`. The parts are built (and exported) per size tried, verified
    once at the last. The report gains ``sizing`` (size, radii, minimum size and its binding
    constraint, the printer, bed fit, ``realization``: what :func:`roomier` did) and
    ``warnings``; ``fixed``: the design's fixed vertices (for :func:`roomier`, used with an
    automatic size and no end-effector) and ``alternatives`` its other loops (index -> joint
    factors), tried by :func:`roomier` too. ``drive``: the design's motor and material density
    (None: the defaults) for the report's ``drive`` entry (masses, torque; :mod:`drive_mass`)."""
    real, note = realization, None
    warnings: list[str] = []
    auto = size_mm is None
    if auto and options.get("effector") is None:
        real, note = roomier(realization, printer, fixed, alternatives)
        if note is not None:
            warnings.append(note)
    attempt: list[str] = []  # the notes of the realization exported
    try:
        result, sz, fit, walls = _fit(real, printer, size_mm, print_in_place, ground,
                                      samples, options, progress, attempt)
    except FabricationError as exc:
        # a link that falls apart at every size tried: another realization, once
        if exc.reason != "falls-apart" or not auto or options.get("effector") is not None:
            raise
        other, note = roomier(real, printer, fixed, alternatives, replace_it=True)
        if other is real:
            raise
        real, attempt = other, []
        warnings.append(f"{note} (a link of the first one falls apart at every size tried)")
        result, sz, fit, walls = _fit(real, printer, size_mm, print_in_place, ground,
                                      samples, options, progress, attempt)
    warnings += attempt
    warnings += notch_warnings(result.assembly)
    if not fit.all():
        warnings.append(f"parts {np.flatnonzero(~fit).tolist()} do not fit the bed "
                        f"{_bed(printer)} mm at the requested {sz.size_mm:.0f} mm")
    report = result.report
    report["verification"] = export.verify_assembly(result.assembly, samples,
                                                    progress=export.stage(progress, 0.5, 1.0))
    report["sizing"] = {
        "size_mm": sz.size_mm, "chosen": "auto" if auto else "requested",
        "bar_radius_mm": sz.bar_radius_mm, "boss_radius_mm": sz.boss_radius_mm,
        "pin_radius_mm": sz.pin_radius_mm, "min_size_mm": sz.min_size_mm,
        "binding_constraint": sz.binding, "printer": printer.name, "bed_mm": printer.bed_mm,
        "wall_mm": printer.wall_mm, "fits_bed": fit.tolist(), "realization": note,
        "realization_radius": real.radius, "realization_separation": real.separation}
    report["warnings"] = warnings
    files = [(n, b) for n, b in result.files if n != "report.json"]
    meshes = {p.name: export.part_trimesh(p) for p in result.assembly.parts}
    report["walls"] = walls
    resting = report.get("grounding", {}).get("link", 0)  # no column: link 0 stays still
    try:  # the parts are verified: a torque that cannot be computed says why, never fails them
        report["drive"] = drive_mass.drive_entry(result.assembly, resting, drive, meshes)
    except ValueError as exc:
        report["drive"] = {"error": str(exc)}
    if not walls["ok"]:
        thin = [n for n, w in walls["parts"].items() if not w["ok"]]
        warnings.append(f"walls under {printer.wall_mm:g} mm on more than 5 % of the surface of "
                        f"{', '.join(thin)} (5th percentile {report['walls']['p5_mm']:.2f} mm)")
    layout = guide.bed_layout(meshes, printer.bed_mm, print_in_place)
    settings = {"printer profile": f"{printer.name} (walls >= {printer.wall_mm:g} mm, pin "
                f"radius >= {printer.pin_radius_mm:g} mm)", "size": f"{sz.size_mm:.0f} mm "
                f"({report['scale_mm_per_unit']:.4g} mm per design unit)"}
    files += guide.guide_pages(result.assembly, meshes, layout, printer.bed_mm, settings)
    return replace(result, files=files + [("report.json", export.report_json(report))])


def _fit(real: Realization, printer: sizing.Printer, size_mm: float | None,
         print_in_place: bool, ground: bool, samples: int, options: dict,
         progress: export.Progress | None, warnings: list[str]
         ) -> tuple[ExportResult, sizing.Sizing, np.ndarray, dict]:
    """Parts of ``real`` built (not verified) at the requested size, or automatically at the
    size that meets the profile, keeps every link in one piece with its walls and fits the
    bed (module docstring); ``(result, sizing, fits_bed mask, walls_report)``. Notes go to
    ``warnings``."""
    lim = sizing.realization_limits(real)
    auto = size_mm is None
    sz = sizing.choose_size(lim, printer, size_mm)
    # no smaller size is tried: the profile's minimum, or where a link fell apart or a wall
    # was thin (a bar notched at a joint: the pins grow with the size, the bosses not)
    floor, grown, why = sz.min_size_mm, 0, ""
    for _ in range(_FIT_ROUNDS + _GROW_ROUNDS + 2):  # sizes tried: first, larger, smaller
        spec = PartSpec(size_mm=sz.size_mm, clearance_mm=printer.clearance_mm,
                        rho_mm=sz.bar_radius_mm, boss_radius_mm=sz.boss_radius_mm,
                        pin_radius_mm=sz.pin_radius_mm, print_in_place=print_in_place,
                        wall_mm=printer.wall_mm)
        build = dict(spec=spec, verify=False, samples=samples, bed_mm=printer.bed_mm,
                     with_guide=False, progress=export.stage(progress, 0.0, 0.5), **options)
        try:
            result = None
            if ground:
                try:
                    result = export.export_parts(real.joint_factors, real.points, real.radius,
                                                 ground=True, **build)
                except FabricationError as exc:
                    if exc.reason != "grounding":
                        raise
                    ground = False  # no column at this size: not tried again
                    warnings.append(f"exported without a grounding column: {exc}")
            if result is None:
                result = export.export_parts(real.joint_factors, real.points, real.radius,
                                             ground=False, **build)
        except FabricationError as exc:
            if exc.reason != "falls-apart" or not auto or grown == _GROW_ROUNDS:
                raise
            floor, grown, why = sz.size_mm * _GROW, grown + 1, "a link falls apart"
            sz = sizing.choose_size(lim, printer, floor)
            continue
        walls, extents = walls_report(result, printer), part_extents(result)
        if not walls["ok"] and auto and grown < _GROW_ROUNDS and \
                sizing.fit_factor(extents, printer).min() >= _GROW:  # only while on the bed
            floor, grown = sz.size_mm * _GROW, grown + 1
            why = f"walls are under {printer.wall_mm:g} mm ({walls['p5_mm']:.2f} mm)"
            sz = sizing.choose_size(lim, printer, floor)
            continue
        fit = sizing.fits_bed(extents, printer)
        column = result.report.get("grounding", {}).get("link")
        if column is not None and not fit.all() and set(np.flatnonzero(~fit)) == {column}:
            # only the column's part is too long: drop the column, keep the size
            ground = False
            warnings.append(f"exported without a grounding column: on link {column} it makes "
                            f"the part {extents[column].max():.0f} mm long, more than the bed "
                            f"{_bed(printer)} mm (choose --ground-link, a larger bed or a "
                            "smaller --size-mm)")
            continue
        if fit.all() or not auto:
            break
        smaller = sz.size_mm * min(float(sizing.fit_factor(extents[~fit], printer).min()), 0.99)
        if smaller < floor:
            need = f"the {sz.binding} needs at least {np.ceil(sz.min_size_mm):.0f} mm" \
                if floor == sz.min_size_mm else f"below {floor:.0f} mm {why}"
            raise FabricationError(
                f"no size fits printer {printer.name!r} (bed {_bed(printer)} mm): {need}, "
                f"where the largest part is {extents.max():.0f} mm long; use a larger printer "
                "(--printer / --bed), thinner walls or a thinner pin", "bad-parameters")
        sz = sizing.choose_size(lim, printer, smaller)
    else:
        raise FabricationError(
            f"the parts did not fit printer {printer.name!r} (bed {_bed(printer)} mm) after "
            f"{_FIT_ROUNDS} smaller sizes (down to {sz.size_mm:.0f} mm); use --size-mm or a "
            "larger bed", "bad-parameters")
    if grown:
        warnings.append(f"size raised to {sz.size_mm:.0f} mm: below {floor:.0f} mm {why} (a "
                        "bar leaning over its pin is notched at the joint)")
    return result, sz, fit, walls


def walls_report(result: ExportResult, printer: sizing.Printer) -> dict:
    """JSON-ready local wall thickness of every part (:mod:`thickness`) against the profile."""
    walls = {p.name: thickness.thickness_summary(export.part_trimesh(p), printer.wall_mm)
             for p in result.assembly.parts}
    return {"wall_mm": printer.wall_mm, "ok": all(w["ok"] for w in walls.values()),
            "p5_mm": min(w["p5_mm"] for w in walls.values()), "parts": walls,
            "method": "chord along the inward normal at 2000 area-uniform surface points per "
                      "part (exact on the mesh; the percentile is a sampling estimate), "
                      "measured up to 4 walls"}


def notch_warnings(asm: Assembly) -> list[str]:
    """One warning per bar that still reaches over the neighbour's boss at a joint
    (``parts.Zone.notch``): the joint zone notches it there (the parts stay apart)."""
    out = []
    for i, z in enumerate(asm.zones):
        for side, mm in enumerate(z.notch):
            if mm > 0:
                link, other = (i, (i + 1) % 6) if side == 0 else ((i + 1) % 6, i)
                out.append(f"link {link}'s bar reaches {mm:.2f} mm over link {other}'s boss at "
                           f"joint {i} (both bars lean over the pin), so the joint zone notches "
                           "it; a larger size, thinner bosses or a longer pin (realization "
                           "offset d) avoid it")
    return out


def _bed(printer: sizing.Printer) -> str:
    return " x ".join(f"{v:g}" for v in printer.bed_mm)
