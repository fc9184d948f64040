"""Physics check speed and verdicts (issue 26, point 7) on the bundled examples.

Run: ``.venv/bin/python benchmarks/bench_physics.py [DESIGN.json ...]``. Each design is solved
and exported in memory as ``paraloop simulate`` does, then one cycle is simulated standing free
on the table and anchored; prints per run the wall time of the simulation (the export's time
apart), the steps, the verdicts and the torques. Asserts nothing.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from app.cli.simulate import run
from paraloop_core import design as design_mod
from paraloop_core import pipeline

ROOT = Path(__file__).resolve().parents[1]


def main(paths: list[str]) -> None:
    files = [Path(p) for p in paths] or sorted((ROOT / "assets" / "designs").glob("*.json"))
    print("design            base      drive  wall s  steps  ok     loop   contacts  tilt deg  "
          "torque dyn / quasi-static N m   (export + run s)")
    for path in files:
        design = design_mod.load_design(path)
        sol = pipeline.solve(design)
        for anchored in (False, True):
            t0 = time.perf_counter()
            rep, _ = run(design, sol, anchored)
            total = time.perf_counter() - t0
            base = "anchored" if rep["anchored"] else "free"
            quasi = rep["peak_torque_quasi_static_nm"]
            dyn = rep["peak_torque_dynamic_nm"]  # None: turned by hand
            print(f"{path.stem:17s} {base:9s} {rep['drive']:5s}  {rep['wall_seconds']:6.2f}  "
                  f"{rep['steps']:5d}  "
                  f"{rep['ok']!s:5s}  {'ok' if rep['completed'] else 'LOST':5s}  "
                  f"{rep['non_adjacent_contacts']:8d}  {rep['base_tilt_deg_max']:8.1f}  "
                  f"{'-' if dyn is None else f'{dyn:.3g}'} / "
                  f"{quasi if quasi is None else f'{quasi:.3g}'}   ({total:.1f})")


if __name__ == "__main__":
    main(sys.argv[1:])
