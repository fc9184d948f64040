"""``paraloop export DESIGN.json --out DIR``: the printed loop, its report and guide.

Solves the design, chooses the realization, size, joints and base for the printer
(``--printer``, ``--bed``, ``--material``, ``--joints``; or at ``--size-mm``;
:mod:`paraloop_core.printed`), builds and verifies the parts over the whole cycle and writes
the parts (``link_<i>.stl`` and the other printed pieces, assembled home pose), the plates
(``paraloop.3mf``, ``paraloop_plate<k>.3mf``), ``assembly.glb``, ``animation.glb``, the
assembly guide (``assembly.md``, ``assembly.html``, ``guide_*.png``), the printed loop's
``result.json``, with ``--3dm`` a Rhino ``paraloop.3dm``, and ``report.json`` into DIR (all or
nothing). DIR is checked before the solve: it must be (or
become) a writable directory holding none of these files unless ``--force`` (which also removes
those an earlier export wrote and this one does not). Exit status 0 when
verification passes, 2 on refused input (nothing written), 3 when no realization was found or
verification fails (files written, the report says why), 1 on an internal error.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TypeVar

from app.cli import outputs
from app.cli.outputs import EXIT_NOT_REALIZED, EXIT_OK, EXIT_REFUSED
from app.cli.solve import solve_realized
from paraloop_core import printed
from paraloop_core.fabrication import drive_mass, printable, profiles, rhino

#: the fixed names written into DIR (plus the numbered ones of :data:`NUMBERED`)
FIXED_NAMES = ("paraloop.3mf", "assembly.glb", "animation.glb", "report.json", "result.json",
               "assembly.md", "assembly.html", "paraloop.3dm", "base_plate.stl", "paraloop.xml")
NUMBERED = ("link_*.stl", "pin_*.stl", "pin_cap_*.stl", "rod_cap_*.stl", "paraloop_plate*.3mf",
            "guide_*.png", "physics_*.stl")
T = TypeVar("T")


def check_out(out: Path, force: bool) -> None:
    """Refuse an unusable ``--out`` before any work (OutputError)."""
    outputs.check_dir_target(out, FIXED_NAMES, force)
    if out.is_dir() and not force:
        for old in sorted(p for pattern in NUMBERED for p in out.glob(pattern)):
            raise outputs.OutputError(f"{old}: already exists (use --force to overwrite)")


def _remove_stale(out: Path, written: set[str]) -> None:
    """After ``--force``: the files of an earlier export this one did not write (a part, plate
    or guide picture fewer, no Rhino file) are removed, so that DIR holds one export."""
    names = [out / n for n in FIXED_NAMES] + [p for pat in NUMBERED for p in out.glob(pat)]
    for old in names:
        if old.name not in written and old.is_file():
            old.unlink()


def cmd_export(args: argparse.Namespace) -> int:
    path = Path(args.design)
    out = outputs.output_path(args.out, "--out")
    check_out(out, args.force)
    try:
        if args.rhino:
            rhino.require()  # before the solve: say at once what is missing
        opts = _options(args)
    except ValueError as exc:
        print(f"error: {path}: {outputs.one_line(exc)}", file=sys.stderr)
        return EXIT_REFUSED
    code, result = solve_realized(path, lambda design, sol: printed.export(
        sol, opts, rhino=args.rhino, simulate=args.simulate,
        progress=None if args.quiet else _print_progress))
    if result is None:
        return code
    files, report, _ = result
    try:
        outputs.write_files(out, files)
        if args.force:
            _remove_stale(out, {name for name, _ in files})
    except OSError as exc:  # checked before the work; a disk filled up since
        print(f"error: {out}: cannot write ({outputs.one_line(exc)})", file=sys.stderr)
        return EXIT_REFUSED
    for warning in report["warnings"]:
        print(f"warning: {path}: {outputs.one_line(warning)}", file=sys.stderr)
    print(f"{path} -> {out}: {len(files)} files; {summary_line(report)}")
    print(f"{path}: {report['choice']['note']}")
    print(f"{path}: {drive_mass.drive_line(report['drive'])}")
    if "physics" in report:
        from app.cli.simulate import summary  # physics only when asked

        print(f"{path}: {summary(report['physics'])}")
        if not report["physics"]["ok"]:
            print(f"error: {path}: the physics check failed (see {out / 'report.json'})",
                  file=sys.stderr)
            return EXIT_NOT_REALIZED
    if not report["verification"]["ok"]:
        print(f"error: {path}: verification failed (see {out / 'report.json'})", file=sys.stderr)
        return EXIT_NOT_REALIZED
    return EXIT_OK


def summary_line(report: dict) -> str:
    """One line a maker reads: size, bars, joints, base, weight, checks."""
    sz, v, b = report["sizing"], report["verification"], report.get("base")
    widths = sz["bar_width_mm"]
    mass = sum(p["mass_g"] for p in report["parts"] if "printed_as" not in p)
    kinds = [j["kind"] for j in report["joints"] if j["kind"] not in ("rod", "dowel")]
    kind = max(set(kinds), key=kinds.count) if kinds else "rod"
    hardware = {"m2": "M2 screws", "m3": "M3 screws", "m4": "M4 screws",
                "printed-pin": "printed pins"}.get(kind, kind)
    base = "no base" if b is None else (
        f"stands on a {b['plate_diameter_mm']:.0f} mm plate" if b["stands"]
        else "base to screw down")
    plates = report["print_layout"]["plates"]
    return (f"{sz['size_mm']:.0f} mm, bars {min(widths):.1f} - {max(widths):.1f} mm wide, "
            f"{hardware}, {base}, {mass:.0f} g on {plates} plate{'s' * (plates > 1)}; parts "
            f"collision-free over the whole cycle: {'yes' if v['ok'] else 'NO'} (least gap "
            f"{v['min_non_adjacent_gap_mm']:.1f} mm)")


def _options(args: argparse.Namespace) -> printable.Options:
    """The export options of the command line (printer profile with ``--bed`` and
    ``--clearance`` applied)."""
    printer = profiles.printer(args.printer, args.bed, args.clearance)
    return printable.Options(printer=printer, material=profiles.MATERIALS[args.material],
                             joints=args.joints, rod=profiles.RODS[args.rod],
                             size_mm=args.size_mm, ground=not args.no_base,
                             ground_link=args.ground_link, samples=args.samples)


def _bed(text: str) -> tuple[float, float, float]:
    try:
        return profiles.parse_bed(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _print_progress(fraction: float, message: str) -> None:
    print(f"  [{100 * fraction:5.1f} %] {message}", file=sys.stderr)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``export`` sub-command."""
    p = subparsers.add_parser("export", help="export printable, verified parts of a design")
    p.add_argument("design", help="design JSON file")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--force", action="store_true", help="overwrite existing files in --out")
    p.add_argument("--size-mm", type=outputs.float_range(0.0, 1e5, lo_open=True), default=None,
                   help="longest side of the loop in mm (default: the largest whose parts "
                        "fit the printer's bed)")
    p.add_argument("--printer", choices=sorted(profiles.PRINTERS), default="generic",
                   help="printer profile: bed, walls, fits (default generic: 250 x 210 x 210 "
                        "mm)")
    p.add_argument("--bed", type=_bed, default=None, help="build volume X,Y,Z in mm")
    p.add_argument("--clearance", type=outputs.float_range(0.0, 5.0), default=None,
                   help="clearance of moving printed faces in mm (default: the printer's)")
    p.add_argument("--material", choices=sorted(profiles.MATERIALS), default="pla",
                   help="print material (density, stiffness; default pla)")
    p.add_argument("--joints", choices=profiles.JOINT_KINDS, default="auto",
                   help="auto (default): M3 screws, M2 where M3 does not fit; m2/m3/m4: "
                        "screw and lock nut through both links; printed-pin: printed pin and "
                        "pressed-on cap; print-in-place: refused for spatial loops, with the "
                        "reason")
    p.add_argument("--rod", choices=sorted(profiles.RODS), default=profiles.DEFAULT_ROD.name,
                   help="the grounding rod (also the grounded joint's axle)")
    p.add_argument("--ground-link", type=int, choices=range(6), default=None,
                   metavar="{0..5}", help="the link the grounding rod holds (default: the one "
                   "that stands best)")
    p.add_argument("--no-base", action="store_true",
                   help="no grounding rod and base plate (the loop is held by hand)")
    p.add_argument("--samples", type=outputs.int_range(8, 100_000), default=720,
                   help="verification samples over the cycle (8..100000)")
    p.add_argument("--simulate", action="store_true",
                   help="also run the physics check (MuJoCo): the parts standing on their base "
                        "through one cycle; writes paraloop.xml (MJCF) and its meshes")
    p.add_argument("--3dm", dest="rhino", action="store_true",
                   help="also write paraloop.3dm (Rhino; needs the rhino3dm package)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=cmd_export)
