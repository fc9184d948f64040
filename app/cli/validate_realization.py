"""``paraloop validate realization``: Table 1 of the paper (Sec. 6.3) on random cubic motions."""

from __future__ import annotations

import argparse
import csv
import functools
import io
import time

from app.cli import batch, outputs
from paraloop_core.validation import table1


def format_table(summary: dict[str, dict]) -> str:
    """Our means beside the paper's, one line per loop kind and source."""
    head = f"{'':8}{'k':>7}{'checks':>11}{'back':>7}{'mindist':>10}{'ratio':>7}{'z':>6}{'s':>5}"
    lines = [head]
    for kind in table1.KINDS:
        m = summary[kind]["means"]
        lines.append(f"{kind + ' ours':8}{m['k']:7.3f}{m['collision_checks']:11.3f}"
                     f"{m['steps_back']:7.3f}{m['min_distance_computations']:10.3f}"
                     f"{m['length_ratio']:7.3f}{m['z']:6d}{m['s']:5d}"
                     f"   ({summary[kind]['successes']}/{summary[kind]['attempts']} realized)")
        pk, pc, pb, pm, pr, pz, ps = table1.PAPER[kind]
        lines.append(f"{kind + ' ppr':8}{pk:7.3f}{pc:11.3f}{pb:7.3f}{pm:10.3f}{pr:7.3f}"
                     f"{pz:6d}{ps:5d}   (1000/1000 realized, Maple18)")
    return "\n".join(lines)


def cmd_realization(args: argparse.Namespace) -> int:
    """Exit status 0 when every loop is realized, 3 otherwise (2: refused arguments)."""
    csv_path = None if args.csv is None else outputs.output_path(args.csv, "--csv")
    if csv_path is not None:  # checked before the (long) run
        outputs.check_file_target(csv_path, args.force)
    start = time.perf_counter()
    with batch.Runner.from_args(args) as runner:
        bar = None if args.quiet else batch.Bar(len(table1.KINDS) * args.motions, "loops")
        rows = table1.run(args.motions, args.seed,
                          functools.partial(runner.values, progress=bar))
    elapsed = time.perf_counter() - start
    if csv_path is not None:
        fields = ["motion", "kind", "ok", "reason", *table1.COLUMNS[:5], "offset_rank",
                  "collision_checks_sequential", "min_clearance_over_rho"]
        text = io.StringIO(newline="")
        writer = csv.DictWriter(text, fieldnames=fields, restval="")
        writer.writeheader()
        writer.writerows(rows)
        outputs.write_files(csv_path.parent, [(csv_path.name, text.getvalue().encode())])
    print(format_table(table1.summarize(rows)))
    print(f"{len(rows)} loops from {args.motions} motions (seed {args.seed}) in {elapsed:.1f} s "
          f"with {runner.workers} worker(s)")
    return outputs.EXIT_OK if all(r["ok"] for r in rows) else outputs.EXIT_NOT_REALIZED


def register(validate_subparsers) -> None:
    """Add the ``realization`` sub-command to the ``validate`` group."""
    p = validate_subparsers.add_parser(
        "realization", help="Table 1: realize AS and DB loops of random cubic motions")
    p.add_argument("--motions", type=outputs.int_range(1, 1_000_000), default=1000,
                   help="number of random cubics (1..1000000)")
    outputs.add_seed(p, "random seed")
    batch.add_arguments(p, batch.VALIDATE_WORKERS)
    p.add_argument("--csv", help="write one row per loop to this CSV file")
    p.add_argument("--force", action="store_true", help="overwrite an existing --csv file")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_realization)
