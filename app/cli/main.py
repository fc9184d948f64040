"""The ``paraloop`` command line: ``solve``, ``validate ...``, ``export``, ``animate``,
``simulate``, ``studio``.

Every failure caused by the input prints one line ``error: <file>: <field>: <reason>`` on stderr;
output paths are checked before any work starts, nothing is overwritten without ``--force`` and
no partial or temporary file is left behind. Exit codes (``docs/result-format.md``): 0 done,
3 solved but not realized, 2 input refused, 1 internal error (``--debug`` shows the traceback),
130 interrupted.
"""

from __future__ import annotations

import argparse
import functools
import sys
import traceback
from collections.abc import Iterator
from pathlib import Path

from app import studio
from app.cli import animate as animate_cmd
from app.cli import batch, outputs, validate_evolution, validate_realization
from app.cli import export as export_cmd
from app.cli import simulate as simulate_cmd
from app.cli.outputs import EXIT_INTERNAL, EXIT_NOT_REALIZED, EXIT_OK, EXIT_REFUSED
from paraloop_core import design as design_mod
from paraloop_core import pipeline
from paraloop_core.errors import RealizationError
from paraloop_core.result import write_json_atomic


class Parser(argparse.ArgumentParser):
    """Usage errors on one line (``error: ...``), exit status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        print(f"error: {self.prog}: {outputs.one_line(message)} (see {self.prog} --help)",
              file=sys.stderr)
        raise SystemExit(EXIT_REFUSED)


def internal_error(where: str, exc: BaseException, debug: bool) -> int:
    """One line for an unexpected exception (a bug); the traceback only with ``--debug``."""
    print(f"error: {where}internal error ({type(exc).__name__}: {outputs.one_line(exc, 200)}); "
          f"{outputs.REPORT} (rerun with --debug for the traceback)", file=sys.stderr)
    if debug:
        traceback.print_exception(exc)
    return EXIT_INTERNAL


def plan_solve(designs: list[Path], out: Path, force: bool) -> tuple[list[Path], bool]:
    """Result path per design and whether ``out`` is a directory; refuses (OutputError) an
    unusable output before any design is read."""
    single = len(designs) == 1 and out.suffix == ".json" and not out.is_dir()
    if single:
        outputs.check_file_target(out, force)
        targets = [out]
    else:
        targets = [out / f"{p.stem}.result.json" for p in designs]
        outputs.check_distinct(targets, designs)
        outputs.check_dir_target(out, [t.name for t in targets], force)
    outputs.check_not_inputs(targets, designs)
    return targets, not single


def _loaded(paths: list[Path]) -> Iterator[design_mod.Design | batch.Outcome]:
    """Each design read here (the paths are this machine's), or the error that refused it."""
    for path in paths:
        try:
            yield design_mod.load_design(path)
        except Exception as exc:  # reported in the design's turn, like a failed solve
            yield batch.Outcome(error=exc)


def _solve_one(path: Path, target: Path, solved: batch.Outcome, out_dir: Path | None) -> int:
    """Report one design's outcome and write its result; returns its exit code."""
    try:
        result = solved.get()
    except RealizationError as exc:
        print(f"error: {path}: {outputs.one_line(exc)}", file=sys.stderr)
        return EXIT_REFUSED if exc.reason == "bad-parameters" else EXIT_NOT_REALIZED
    except ValueError as exc:  # ParaloopError: a refused file or degenerate design
        print(f"error: {path}: {outputs.one_line(exc)}", file=sys.stderr)
        return EXIT_REFUSED
    real = result.get("realization", {})
    if out_dir is not None:
        with outputs.created_dir(out_dir):
            write_json_atomic(target, result)
    else:
        write_json_atomic(target, result)
    print(f"{path} -> {target}")
    if real.get("status", "found") != "found":
        print(f"warning: {path}: solved, but no collision-free realization was found "
              f"({outputs.one_line(real.get('reason', 'no reason given'))})", file=sys.stderr)
        return EXIT_NOT_REALIZED
    return EXIT_OK


def cmd_solve(args: argparse.Namespace) -> int:
    """Solve each design (in this process, or as tasks of a Dask cluster: ``--workers``,
    ``--dask``); write ``<stem>.result.json`` per solved design, in input order."""
    designs = [Path(name) for name in args.designs]
    out = Path(args.output)
    targets, is_dir = plan_solve(designs, out, args.force)
    task = functools.partial(pipeline.solve_to_dict, realize=not args.no_realize)
    bar = batch.Bar(len(designs), "designs") if sys.stderr.isatty() else None
    codes = []
    with batch.Runner.from_args(args) as runner:
        solved = runner.outcomes(task, _loaded(designs), bar)
        for path, target, outcome in zip(designs, targets, solved, strict=True):
            if bar is not None:
                bar.clear()
            try:
                codes.append(_solve_one(path, target, outcome, out if is_dir else None))
            except (KeyboardInterrupt, outputs.OutputError):
                raise
            except OSError as exc:
                print(f"error: {target}: cannot write ({outputs.one_line(exc)})",
                      file=sys.stderr)
                codes.append(EXIT_REFUSED)
            except Exception as exc:  # a bug: report it, go on with the other designs
                codes.append(internal_error(f"{path}: ", exc, args.debug))
    for code in (EXIT_INTERNAL, EXIT_REFUSED, EXIT_NOT_REALIZED):
        if code in codes:
            return code
    return EXIT_OK


def _add_debug(parser: argparse.ArgumentParser, top: bool = True) -> None:
    """``--debug`` accepted before or after the sub-command (tracebacks of internal errors)."""
    parser.add_argument("--debug", action="store_true",
                        default=False if top else argparse.SUPPRESS,
                        help="print the traceback of an internal error")
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child in action.choices.values():
                _add_debug(child, top=False)


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="paraloop", description="Design invertible paradoxical 6R loops.")
    sub = parser.add_subparsers(dest="command", required=True)
    solve = sub.add_parser("solve", help="solve design files and write result JSON")
    solve.add_argument("designs", nargs="+", help="design JSON files")
    solve.add_argument("-o", "--output", required=True,
                       help="output directory, or a .json file for a single design")
    solve.add_argument("--no-realize", action="store_true",
                       help="skip the collision-free realization")
    solve.add_argument("--force", action="store_true", help="overwrite existing result files")
    batch.add_arguments(solve)
    solve.set_defaults(func=cmd_solve)
    validate = sub.add_parser("validate", help="statistical validations of the paper")
    validate_sub = validate.add_subparsers(dest="what", required=True)
    # Sub-commands living in their own modules register themselves here.
    for module in _COMMAND_MODULES:
        module.register(sub)
    for module in _VALIDATE_MODULES:
        module.register(validate_sub)
    _add_debug(parser)
    return parser


_COMMAND_MODULES: list = [studio, export_cmd, animate_cmd, simulate_cmd]
_VALIDATE_MODULES: list = [validate_realization, validate_evolution]


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code (never raises, never prints a traceback
    unless ``--debug``)."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error (2, already printed)
        return exc.code if isinstance(exc.code, int) else EXIT_REFUSED
    debug = bool(getattr(args, "debug", False))
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return outputs.EXIT_INTERRUPTED
    except (ValueError, OSError) as exc:  # bad input or unusable output: one line
        print(f"error: {outputs.one_line(exc)}", file=sys.stderr)
        return EXIT_REFUSED
    except Exception as exc:
        return internal_error("", exc, debug)


if __name__ == "__main__":
    sys.exit(main())
