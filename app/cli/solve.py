"""``paraloop solve DESIGN.json... -o OUT``: one result JSON per design (``docs/result-format.md``),
in this process or as tasks of a Dask cluster (``--workers``, ``--dask``).

The output is checked before any design is read; each design's failure is reported in its turn
(one line naming the file and, for a refused design, the field) and the others go on. Only the
core's pipeline is imported: no studio, mesh or fabrication library.
"""

from __future__ import annotations

import argparse
import functools
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TypeVar

from app.cli import batch, outputs
from app.cli.outputs import EXIT_INTERNAL, EXIT_NOT_REALIZED, EXIT_OK, EXIT_REFUSED
from paraloop_core import design as design_mod
from paraloop_core import pipeline
from paraloop_core.design import Design
from paraloop_core.errors import ParaloopError, RealizationError
from paraloop_core.result import write_json_atomic

T = TypeVar("T")


def plan_solve(designs: list[Path], out: Path, force: bool) -> tuple[list[Path], bool]:
    """Result path per design and whether ``out`` is a directory; refuses (OutputError) an
    unusable output before any design is read."""
    try:
        single = len(designs) == 1 and out.suffix == ".json" and not out.is_dir()
    except OSError as exc:  # a name too long
        raise outputs.OutputError(f"{outputs.one_line(str(out), 200)}: cannot use it "
                                  f"({exc.strerror or exc})") from exc
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
        outputs.check_interrupt()
        print(f"error: {path}: {outputs.one_line(exc)}", file=sys.stderr)
        return EXIT_REFUSED if exc.reason == "bad-parameters" else EXIT_NOT_REALIZED
    except (ValueError, OSError) as exc:  # ParaloopError: a refused file or degenerate design
        outputs.check_interrupt()  # a failure after Ctrl-C is the interrupt's
        print(f"error: {path}: {outputs.one_line(exc)}", file=sys.stderr)
        return EXIT_REFUSED
    real = result.get("realization", {})
    try:
        if out_dir is not None:
            with outputs.created_dir(out_dir):
                write_json_atomic(target, result)
        else:
            write_json_atomic(target, result)
    except ParaloopError as exc:  # a non-finite value (NumericalError): nothing written
        print(f"error: {path}: {outputs.one_line(exc)}", file=sys.stderr)
        return EXIT_REFUSED
    except OSError as exc:
        print(f"error: {target}: cannot write ({outputs.one_line(exc)})", file=sys.stderr)
        return EXIT_REFUSED
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
    out = outputs.output_path(args.output, "-o")
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
            except Exception as exc:  # a bug: report it, go on with the other designs
                codes.append(outputs.internal_error(f"{path}: ", exc, args.debug))
    for code in (EXIT_INTERNAL, EXIT_REFUSED, EXIT_NOT_REALIZED):
        if code in codes:
            return code
    return EXIT_OK


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``solve`` sub-command."""
    solve = subparsers.add_parser("solve", help="solve design files and write result JSON")
    solve.add_argument("designs", nargs="+", help="design JSON files")
    solve.add_argument("-o", "--output", required=True,
                       help="output directory, or a .json file for a single design")
    solve.add_argument("--no-realize", action="store_true",
                       help="skip the collision-free realization")
    solve.add_argument("--force", action="store_true", help="overwrite existing result files")
    batch.add_arguments(solve)
    solve.set_defaults(func=cmd_solve)


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
