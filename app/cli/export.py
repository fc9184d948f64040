"""``paraloop export DESIGN.json --out DIR``: printable parts (STL, 3MF, GLB) and the report.

Solves the design (with its realization), sizes the parts for the printer (``--printer``,
``--bed``; or at ``--size-mm``; :mod:`paraloop_core.fabrication.printable`), builds and verifies
them over the cycle and writes ``link_<i>.stl`` (home pose), ``paraloop.3mf`` (the parts laid
out on the bed; ``paraloop_plate<k>.3mf`` for further plates), ``assembly.glb``, the assembly
guide ``assembly.md`` with ``assembly_step_<k>.png``, with ``--3dm`` a Rhino ``paraloop.3dm``,
and ``report.json`` into DIR (all or nothing). DIR is checked before the solve: it must be (or
become) a writable directory holding none of these files unless ``--force``. Exit status 0 when
verification passes, 2 on refused input (nothing written), 3 when no realization was found or
verification fails (files written, the report says why), 1 on an internal error.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TypeVar

from app.cli import outputs
from app.cli.outputs import EXIT_NOT_REALIZED, EXIT_OK, EXIT_REFUSED
from paraloop_core import design as design_mod
from paraloop_core import pipeline
from paraloop_core.design import Design
from paraloop_core.errors import ParaloopError, RealizationError
from paraloop_core.fabrication import drive_mass, printable, rhino, sizing

#: the fixed names written into DIR (plus the numbered ones of :data:`NUMBERED`)
FIXED_NAMES = ("paraloop.3mf", "assembly.glb", "report.json", "assembly.md", "paraloop.3dm")
NUMBERED = ("link_*.stl", "paraloop_plate*.3mf", "assembly_step_*.png")
T = TypeVar("T")


def check_out(out: Path, force: bool) -> None:
    """Refuse an unusable ``--out`` before any work (OutputError)."""
    outputs.check_dir_target(out, FIXED_NAMES, force)
    if out.is_dir() and not force:
        for old in sorted(p for pattern in NUMBERED for p in out.glob(pattern)):
            raise outputs.OutputError(f"{old}: already exists (use --force to overwrite)")


def solve_realized(path: Path, work: Callable[[Design, pipeline.Solution], T]
                   ) -> tuple[int, T | None]:
    """Load and solve the design at ``path`` (its realization enabled) and run ``work(design,
    solution)`` on the realized one: ``(EXIT_OK, value)``, or the exit code after one error
    line (not realized: 3; refused input: 2) and None. Shared by ``export`` and ``animate``."""
    try:
        design = design_mod.load_design(path)
        if not design.realization.enabled:
            raise ParaloopError("the design has no realization (enable it in the design file)",
                                "bad-parameters")
        sol = pipeline.solve(design)
        if sol.realization is None:
            reason = (sol.realization_report or {}).get("reason", "no reason given")
            print(f"error: {path}: no collision-free realization found "
                  f"({outputs.one_line(reason)})", file=sys.stderr)
            return EXIT_NOT_REALIZED, None
        return EXIT_OK, work(design, sol)
    except RealizationError as exc:
        outputs.check_interrupt()
        print(f"error: {path}: {outputs.one_line(exc)}", file=sys.stderr)
        return (EXIT_REFUSED if exc.reason == "bad-parameters" else EXIT_NOT_REALIZED), None
    except (ValueError, OSError) as exc:  # ParaloopError, any other bad-input ValueError, a
        outputs.check_interrupt()  # mesh unreadable; after Ctrl-C: the interrupt's
        print(f"error: {path}: {outputs.one_line(exc)}", file=sys.stderr)
        return EXIT_REFUSED, None


def cmd_export(args: argparse.Namespace) -> int:
    path = Path(args.design)
    out = outputs.output_path(args.out, "--out")
    check_out(out, args.force)
    try:
        if args.rhino:
            rhino.require()  # before the solve: say at once what is missing
        printer = _printer(args)
    except ValueError as exc:
        print(f"error: {path}: {outputs.one_line(exc)}", file=sys.stderr)
        return EXIT_REFUSED
    code, result = solve_realized(path, lambda design, sol: printable.export_printable(
        sol.realization, printer=printer, size_mm=args.size_mm,
        print_in_place=args.print_in_place, ground=not args.no_ground,
        ground_axis=args.ground_axis, ground_link=args.ground_link,
        space_radius=args.carve_radius, resolution=args.resolution, samples=args.samples,
        effector=sol.end_effector, rhino=args.rhino, fixed=dict(design.realization.fixed),
        alternatives=sol.other_loops(), drive=design.drive,
        progress=None if args.quiet else _print_progress))
    if result is None:
        return code
    try:
        outputs.write_files(out, result.files)
    except OSError as exc:  # checked before the work; a disk filled up since
        print(f"error: {out}: cannot write ({outputs.one_line(exc)})", file=sys.stderr)
        return EXIT_REFUSED
    ver, sz = result.report["verification"], result.report["sizing"]
    for warning in result.report["warnings"]:
        print(f"warning: {path}: {outputs.one_line(warning)}", file=sys.stderr)
    print(f"{path} -> {out}: {len(result.files)} files at {sz['size_mm']:.0f} mm ({sz['chosen']}; "
          f"bars {sz['bar_radius_mm']:.2f} mm, bosses {sz['boss_radius_mm']:.2f} mm, pins "
          f"{sz['pin_radius_mm']:.2f} mm radius; {printer.name} bed); walls "
          f"{result.report['walls']['p5_mm']:.2f} mm (5th percentile); min gap "
          f"{ver['min_gap_mm']:.3f} mm, "
          f"continuous bound {ver['continuous_min_gap_mm']:.3f} mm, "
          f"joint clearance {ver['joint_clearance_mm']:.3f} mm")
    print(f"{path}: {drive_mass.drive_line(result.report['drive'])}")
    if ver["ok"] and not ver["printable"]:
        print(f"warning: {path}: parts are collision-free but some gaps are under half the "
              "clearance and may fuse when printed", file=sys.stderr)
    if not ver["ok"]:
        print(f"error: {path}: verification failed (see {out / 'report.json'})", file=sys.stderr)
        return EXIT_NOT_REALIZED
    return EXIT_OK


def _printer(args: argparse.Namespace) -> sizing.Printer:
    """The printer profile of ``--printer``, with ``--bed`` and ``--clearance`` applied."""
    printer = sizing.PRINTERS[args.printer]
    if args.bed is not None:
        printer = replace(printer, name=f"{printer.name}, bed {args.bed}", bed_mm=args.bed)
    if args.clearance is not None:
        printer = replace(printer, clearance_mm=args.clearance)
    return printer


def _bed(text: str) -> tuple[float, float, float]:
    side = outputs.float_range(0.0, 1e4, lo_open=True)
    parts = text.split(",")
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"--bed needs X,Y,Z in mm, got {text!r}")
    return tuple(side(v) for v in parts)


def _print_progress(fraction: float, message: str) -> None:
    print(f"  [{100 * fraction:5.1f} %] {message}", file=sys.stderr)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``export`` sub-command."""
    p = subparsers.add_parser("export", help="export printable, verified parts of a design")
    p.add_argument("design", help="design JSON file")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--force", action="store_true", help="overwrite existing files in --out")
    p.add_argument("--size-mm", type=outputs.float_range(0.0, 1e5, lo_open=True), default=None,
                   help="longest side of the linkage in mm (default: chosen for the printer)")
    p.add_argument("--printer", choices=sorted(sizing.PRINTERS), default="generic",
                   help="printer profile: bed, walls >= 2 mm, pin radius >= 1 mm, clearance "
                        "0.3 mm (default generic: 250 x 210 x 210 mm)")
    p.add_argument("--bed", type=_bed, default=None, help="build volume X,Y,Z in mm")
    p.add_argument("--clearance", type=outputs.float_range(0.0, 100.0), default=None,
                   help="joint clearance in mm (default: the printer's, 0.3)")
    p.add_argument("--print-in-place", action="store_true", help="captured pins with heads")
    p.add_argument("--no-ground", action="store_true", help="no grounding column")
    p.add_argument("--ground-link", type=int, choices=range(6), default=None,
                   help="link that stands on the ground (default: the one whose column keeps "
                        "the largest clearance)")
    p.add_argument("--ground-axis", type=int, choices=range(6), default=None,
                   help="axis carrying the grounding column, one of the grounded link's two "
                        "(link g: A_{g-1} or A_g; default: the best)")
    p.add_argument("--carve-radius", type=outputs.float_range(0.0, 1e12, lo_open=True),
                   default=None,
                   help="carve design spaces of this radius (design units) as link bodies")
    p.add_argument("--resolution", type=outputs.int_range(8, 1024), default=None,
                   help="voxels along a design space (8..1024; default: automatic, 128..256 "
                        "so that every space is several voxels thick)")
    p.add_argument("--samples", type=outputs.int_range(8, 100_000), default=720,
                   help="verification samples (8..100000)")
    p.add_argument("--3dm", dest="rhino", action="store_true",
                   help="also write paraloop.3dm (Rhino; needs the rhino3dm package)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=cmd_export)
