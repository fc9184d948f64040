"""The ``paraloop`` command line: ``solve``, ``validate ...``, ``export``, ``studio``.

Every failure caused by the input prints one line ``error: <file>: <field>: <reason>`` on stderr
and exits non-zero; no partial output file is ever written.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from app import studio
from app.cli import export as export_cmd
from app.cli import validate_evolution, validate_realization
from paraloop_core import design as design_mod
from paraloop_core import pipeline


def _out_path(out: Path, design_path: Path, several: bool) -> Path:
    if not several and out.suffix == ".json":
        return out
    return out / f"{design_path.stem}.result.json"


def cmd_solve(args: argparse.Namespace) -> int:
    """Solve each design in one process; write ``<stem>.result.json`` per good design."""
    out = Path(args.output)
    several = len(args.designs) > 1 or out.suffix != ".json"
    if several:
        out.mkdir(parents=True, exist_ok=True)
    failures = 0
    for name in args.designs:
        path = Path(name)
        try:
            design = design_mod.load_design(path)
            result = pipeline.result_to_dict(pipeline.solve(design, realize=not args.no_realize))
        except ValueError as exc:  # ParaloopError and any other bad-input ValueError
            print(f"error: {path}: {exc}", file=sys.stderr)
            failures += 1
            continue
        target = _out_path(out, path, several)
        pipeline.write_json_atomic(target, result)
        print(f"{path} -> {target}")
    return 1 if failures else 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="paraloop", description="Design invertible paradoxical 6R loops."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    solve = sub.add_parser("solve", help="solve design files and write result JSON")
    solve.add_argument("designs", nargs="+", help="design JSON files")
    solve.add_argument("-o", "--output", required=True,
                       help="output directory, or a .json file for a single design")
    solve.add_argument("--no-realize", action="store_true",
                       help="skip the collision-free realization")
    solve.set_defaults(func=cmd_solve)
    validate = sub.add_parser("validate", help="statistical validations of the paper")
    validate_sub = validate.add_subparsers(dest="what", required=True)
    # Sub-commands living in their own modules register themselves here.
    for module in _COMMAND_MODULES:
        module.register(sub)
    for module in _VALIDATE_MODULES:
        module.register(validate_sub)
    return parser


_COMMAND_MODULES: list = [studio, export_cmd]
_VALIDATE_MODULES: list = [validate_realization, validate_evolution]


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ValueError as exc:  # bad input reaching the core: one line, never a traceback
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
