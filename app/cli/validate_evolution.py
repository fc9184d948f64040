"""``paraloop validate evolution``: Fig. 16 of the paper (Sec. 6.3), many random starts."""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from app.cli import batch, outputs
from paraloop_core.validation import fig16


def _progress_bar(start: float):
    def show(fraction: float, message: str) -> None:
        outputs.draw_bar(fraction, f"{message} {time.perf_counter() - start:.0f} s")

    return show


NAMES = ("fig16.png", "fig16.csv", "fig16_summary.json")


def cmd_evolution(args: argparse.Namespace) -> int:
    out = outputs.output_path(args.out, "--out")
    outputs.check_dir_target(out, NAMES, args.force)  # before the (long) run
    with batch.Runner.from_args(args) as runner:
        res = fig16.run(args.starts, args.targets, args.seed, runner.workers,
                        args.max_iterations,
                        None if args.quiet else _progress_bar(time.perf_counter()),
                        runner.values)
    final = res.costs[:, -1]
    status = {s: res.status.count(s) for s in sorted(set(res.status))}
    summary = {
        "starts": args.starts, "targets": args.targets, "seed": args.seed,
        "workers": runner.workers, "seconds": round(res.seconds, 2),
        "iterations_max": int(res.costs.shape[1] - 1),
        "final_cost": {"best": float(final.min()), "median": float(np.median(final)),
                       "mean": float(final.mean()), "worst": float(final.max())},
        "exact_fits": int(np.sum(final <= 1e-8)), "status": status,
        "best_start": res.best, "worst_start": res.worst,
    }
    with outputs.staged_dir(out) as tmp:
        fig16.write_csv(res, tmp / "fig16.csv")
        fig16.plot(res, tmp / "fig16.png")
        (tmp / "fig16_summary.json").write_text(json.dumps(summary, indent=1) + "\n",
                                                encoding="utf-8")
    print(f"{args.starts} starts on {args.targets} targets (seed {args.seed}) in "
          f"{res.seconds:.1f} s with {runner.workers} worker(s)")
    print(f"final cost: best {final.min():.3g}, median {np.median(final):.3g}, "
          f"worst {final.max():.3g}; {summary['exact_fits']} starts <= 1e-8; status {status}")
    print(f"wrote {out / 'fig16.png'}, {out / 'fig16.csv'}, {out / 'fig16_summary.json'}")
    return 0


def register(validate_subparsers) -> None:
    """Add the ``evolution`` sub-command to the ``validate`` group."""
    p = validate_subparsers.add_parser(
        "evolution", help="Fig. 16: evolution from many random starts on sampled targets")
    p.add_argument("--starts", type=outputs.int_range(1, 100_000), default=500,
                   help="number of random starts (1..100000)")
    p.add_argument("--targets", type=outputs.int_range(5, 1000), default=10,
                   help="number of target poses (5..1000)")
    outputs.add_seed(p, "seed of the target motion and starts")
    batch.add_arguments(p, batch.VALIDATE_WORKERS)
    p.add_argument("--max-iterations", type=outputs.int_range(1, 10_000), default=100,
                   help="iteration cap per start (1..10000)")
    p.add_argument("--out", default="out/fig16", help="output directory (PNG, CSV, JSON)")
    p.add_argument("--force", action="store_true", help="overwrite existing output files")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_evolution)
