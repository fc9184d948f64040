"""``paraloop export DESIGN.json --out DIR``: printable parts (STL, 3MF, GLB) and the report.

Solves the design (with its realization), builds the parts at ``--size-mm``, verifies them
over the cycle and writes ``link_<i>.stl``, ``paraloop.3mf``, ``assembly.glb`` and
``report.json`` into DIR. Exit status 0 when verification passes, 1 on bad input (nothing
written) or when verification fails (files written, report says why).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from paraloop_core import design as design_mod
from paraloop_core import pipeline
from paraloop_core.errors import ParaloopError
from paraloop_core.fabrication import export
from paraloop_core.fabrication.parts import PartSpec


def cmd_export(args: argparse.Namespace) -> int:
    path = Path(args.design)
    try:
        sol = pipeline.solve(design_mod.load_design(path))
        real = sol.realization
        if real is None:
            raise ParaloopError("the design has no realization (enable it in the design file)",
                                "bad-parameters")
        spec = PartSpec(size_mm=args.size_mm, clearance_mm=args.clearance,
                        print_in_place=args.print_in_place)
        result = export.export_parts(
            real.joint_factors, real.points, real.radius, spec=spec, ground=not args.no_ground,
            ground_axis=args.ground_axis, space_radius=args.carve_radius,
            resolution=args.resolution, samples=args.samples, effector=sol.end_effector,
            progress=None if args.quiet else _print_progress)
    except ValueError as exc:  # ParaloopError and any other bad-input ValueError
        print(f"error: {path}: {exc}", file=sys.stderr)
        return 1
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name, data in result.files:
        (out / name).write_bytes(data)
    ver = result.report["verification"]
    print(f"{path} -> {out}: {len(result.files)} files; min gap {ver['min_gap_mm']:.3f} mm, "
          f"continuous bound {ver['continuous_min_gap_mm']:.3f} mm, "
          f"joint clearance {ver['joint_clearance_mm']:.3f} mm")
    if ver["ok"] and not ver["printable"]:
        print(f"warning: {path}: parts are collision-free but some gaps are under half the "
              "clearance and may fuse when printed", file=sys.stderr)
    if not ver["ok"]:
        print(f"error: {path}: verification failed (see {out / 'report.json'})", file=sys.stderr)
        return 1
    return 0


def _print_progress(fraction: float, message: str) -> None:
    print(f"  [{100 * fraction:5.1f} %] {message}", file=sys.stderr)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``export`` sub-command."""
    p = subparsers.add_parser("export", help="export printable, verified parts of a design")
    p.add_argument("design", help="design JSON file")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--size-mm", type=float, default=150.0,
                   help="longest side of the linkage in mm (default 150)")
    p.add_argument("--clearance", type=float, default=0.3,
                   help="joint clearance in mm (default 0.3)")
    p.add_argument("--print-in-place", action="store_true", help="captured pins with heads")
    p.add_argument("--no-ground", action="store_true", help="no grounding column")
    p.add_argument("--ground-axis", type=int, choices=(0, 5), default=None,
                   help="base-link axis carrying the grounding column (default: first that works)")
    p.add_argument("--carve-radius", type=float, default=None,
                   help="carve design spaces of this radius (design units) as link bodies")
    p.add_argument("--resolution", type=int, default=128, help="voxels along a design space")
    p.add_argument("--samples", type=int, default=720, help="verification samples")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=cmd_export)
