"""Physics check speed and verdicts (issue 26, point 7) on the bundled examples or random designs.

Run: ``.venv/bin/python benchmarks/bench_physics.py [DESIGN.json ...]`` (the examples: free on the
table and anchored, driven by the motor, as ``paraloop simulate`` and ``--anchored`` do), or
``--random N [--start S]``: random generic designs (``tests/independent/generic_designs.py``) as
``paraloop simulate`` checks them by default (the motor, or turned by hand where one motor
cannot hold the loop). Each design is solved and exported in memory; prints per run the wall
time of the simulation (the export's time apart), the drive, the steps, the verdicts and the
torques, then the share that passes. Asserts nothing.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from app.cli.simulate import run
from paraloop_core import design as design_mod
from paraloop_core import pipeline

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from independent.generic_designs import random_design  # noqa: E402


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("designs", nargs="*", help="design files (default: the examples)")
    ap.add_argument("--random", type=int, default=0, metavar="N", help="N random designs")
    ap.add_argument("--start", type=int, default=0, help="first random seed")
    args = ap.parse_args(argv)
    if args.random:
        items = [(f"random-{s}", design_mod.design_from_dict(random_design(s)), (None,))
                 for s in range(args.start, args.start + args.random)]
    else:
        files = [Path(p) for p in args.designs] or \
            sorted((ROOT / "assets" / "designs").glob("*.json"))
        items = [(p.stem, design_mod.load_design(p), (False, True)) for p in files]
    print("design            base      drive  wall s  steps  ok     loop   contacts  tilt deg  "
          "torque dyn / quasi-static N m   (export + run s)")
    runs = passed = 0
    for name, design, bases in items:
        try:
            sol = pipeline.solve(design)
        except ValueError as exc:  # the solver's refusals (a non-generic motion)
            print(f"{name:17s} not solved: {' '.join(str(exc).split()[:12])}")
            continue
        if sol.realization is None:
            print(f"{name:17s} not realized")
            continue
        for anchored in bases:
            t0 = time.perf_counter()
            try:
                rep, _ = run(design, sol, bool(anchored))
            except ValueError as exc:  # the export's refusals
                print(f"{name:17s} refused: {' '.join(str(exc).split()[:12])}")
                break
            total = time.perf_counter() - t0
            runs, passed = runs + 1, passed + bool(rep["ok"])
            base = "anchored" if rep["anchored"] else "free"
            quasi = rep["peak_torque_quasi_static_nm"]
            dyn = rep["peak_torque_dynamic_nm"]  # None: turned by hand
            print(f"{name:17s} {base:9s} {rep['drive']:5s}  {rep['wall_seconds']:6.2f}  "
                  f"{rep['steps']:5d}  "
                  f"{rep['ok']!s:5s}  {'ok' if rep['completed'] else 'LOST':5s}  "
                  f"{rep['non_adjacent_contacts']:8d}  {rep['base_tilt_deg_max']:8.1f}  "
                  f"{'-' if dyn is None else f'{dyn:.3g}'} / "
                  f"{quasi if quasi is None else f'{quasi:.3g}'}   ({total:.1f})")
    print(f"{passed} of {runs} runs pass")


if __name__ == "__main__":
    main()
