"""``paraloop simulate DESIGN.json [--out DIR]``: the physics check of the printed parts.

Solves the design, makes its printed loop in memory as ``paraloop export`` does (the generic
printer, the export's own verification over the cycle: its gaps decide whether the motor's
torque would bend links into each other, and so the drive) and runs one cycle
(:func:`printed.physics_check`): standing free on its base on a table, or anchored
(``--anchored``; also when there is no base); driven by its motor, or turned by hand where one
motor cannot hold the loop (``--drive``). Prints one summary line; with ``--out``, writes
``physics.json`` (the report), ``paraloop.xml`` (MJCF) and the bodies' meshes
``physics_<body>.stl`` (mm, the standing sculpture's frame) into DIR, all or nothing, checked
before the solve. Exit status 0 when the check passes, 3 when it fails or no realization was
found (files written), 2 on refused input, 1 on an internal error.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

from app.cli import outputs
from app.cli.outputs import EXIT_NOT_REALIZED, EXIT_OK
from app.cli.solve import solve_realized
from paraloop_core import pipeline, printed
from paraloop_core.design import Design
from paraloop_core.fabrication import printable

FIXED_NAMES = ("physics.json", "paraloop.xml")
NUMBERED = "physics_*.stl"


def check_out(out: Path, force: bool) -> None:
    """Refuse an unusable ``--out`` before any work (OutputError)."""
    outputs.check_dir_target(out, FIXED_NAMES, force)
    if out.is_dir() and not force:
        for old in sorted(out.glob(NUMBERED)):
            raise outputs.OutputError(f"{old}: already exists (use --force to overwrite)")


def run(design: Design, sol: pipeline.Solution, anchored: bool, hand: bool | None = None
        ) -> tuple[dict, list]:
    """``(physics.json content, files)`` of one design (module docstring); ``hand``: turned
    by hand or by the motor (None: by hand where one motor cannot hold the loop)."""
    opts = printable.Options()
    made, _ = printed.make(sol, opts)
    if anchored and made.base is not None:
        made = replace(made, base=None)  # the base fixed in the world: mounted
    content, files = printed.physics_check(made, opts, design.drive, hand)
    content = {**content, "design": design.name, "size_mm": made.report["sizing"]["size_mm"],
               "warnings": list(made.report["warnings"]) + (
                   [] if made.base is not None or anchored else
                   ["the parts have no base: simulated mounted by their resting link"])}
    return content, [("physics.json", (json.dumps(content, indent=1) + "\n").encode()),
                     *files]


def summary(rep: dict) -> str:
    """One line for people: verdict, run, drive, loop, contacts, base, torques."""
    if rep["drive"] == "hand":
        base = f"held, link {rep['hand_link']} turned by hand"
    elif rep["anchored"]:
        base = "anchored"
    else:
        base = ("stands" if rep["stands"] else "tips") + \
            f" (tilt {rep['base_tilt_deg_max']:.1f} deg, lift {rep['base_lift_mm_max']:.2f} mm)"
    quasi = rep["peak_torque_quasi_static_nm"]
    torque = "" if rep["drive"] == "hand" else (
        f"; peak torque {rep['peak_torque_dynamic_nm']:.3g} N*m dynamic, "
        + (f"{quasi:.3g} quasi-static" if quasi is not None else "quasi-static unknown"))
    return (f"physics {'ok' if rep['ok'] else 'FAILED'}: {rep['sim_seconds']:.1f} s cycle in "
            f"{rep['wall_seconds']:.1f} s; loop {'followed' if rep['completed'] else 'LOST'} "
            f"(pose error {rep['max_pose_error_mm']:.3g} mm, tolerance "
            f"{rep['pose_tolerance_mm']:.3g}); non-adjacent contacts "
            f"{rep['non_adjacent_contacts']}; base {base}{torque}")


def cmd_simulate(args: argparse.Namespace) -> int:
    path = Path(args.design)
    out = Path(args.out) if args.out else None
    if out is not None:
        check_out(out, args.force)
    hand = {"auto": None, "motor": False, "hand": True}[args.drive]
    code, done = solve_realized(path, lambda design, sol: run(design, sol, args.anchored, hand))
    if done is None:
        return code
    rep, files = done
    if out is not None:
        outputs.write_files(out, files)
    print(f"{path}{f' -> {out}' if out else ''}: {summary(rep)}")
    for note in rep["warnings"]:
        print(f"warning: {path}: {outputs.one_line(note)}", file=sys.stderr)
    if rep["unchecked_bodies"]:
        print(f"warning: {path}: contacts not checked for {', '.join(rep['unchecked_bodies'])} "
              "(no convex pieces)", file=sys.stderr)
    return EXIT_OK if rep["ok"] else EXIT_NOT_REALIZED


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``simulate`` sub-command."""
    p = subparsers.add_parser("simulate", help="MuJoCo physics check of the printed parts")
    p.add_argument("design", help="design JSON file")
    p.add_argument("--out", default=None,
                   help="output directory for physics.json, paraloop.xml (MJCF) and the STLs")
    p.add_argument("--anchored", action="store_true",
                   help="the base is fixed (mounted) instead of standing on a table")
    p.add_argument("--drive", choices=("auto", "motor", "hand"), default="auto",
                   help="turn the loop by its motor, or by hand (the base held, a link across "
                        "the loop moved along its path); auto (default): by hand where the "
                        "drive report says one motor cannot hold the loop")
    p.add_argument("--force", action="store_true", help="overwrite existing files in --out")
    p.set_defaults(func=cmd_simulate)
