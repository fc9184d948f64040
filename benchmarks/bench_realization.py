"""Timings of the realization pipeline (prints figures; no asserts).

    .venv/bin/python benchmarks/bench_realization.py [--loops 200] [--table-motions 40]

1. exact thin collision check of one 6R (9 pairs, whole cycle), motions precomputed and not;
2. exact minimum distance of the 42 offset pairs of one realization;
3. full ``realize`` over random AS and DB loops (median, 95th percentile, max);
4. ``validate realization`` on a few motions with 2 workers (a local Dask cluster, as the command
   line runs it), extrapolated to 1000 motions.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from app.cli import batch  # noqa: E402
from paraloop_core.realization import collision, polyline, realize  # noqa: E402
from paraloop_core.validation import table1  # noqa: E402


def _best_ms(fn, repeat: int = 30) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--loops", type=int, default=200, help="AS + DB loops for realize timings")
    ap.add_argument("--table-motions", type=int, default=40, help="motions for the Table 1 run")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    print(f"cpus={os.cpu_count()} load={os.getloadavg()[0]:.2f} (timings are medians)")

    jf = table1.random_loops(args.seed, 1)[0, 0]
    _, v0 = polyline.shortest_polyline(jf)
    free = realize.realize(jf).thin  # collision-free: all nine pairs are fully checked
    motions = collision.thin_pair_motions(jf)
    ms = _best_ms(lambda: collision.colliding_polylines(motions, free[None]))
    print(f"thin collision check, 1 polyline, motions precomputed: {ms:.2f} ms")
    ms = _best_ms(lambda: collision.check_polylines(jf, free))
    print(f"thin collision check, 1 polyline, incl. relative motions: {ms:.2f} ms")
    _, u = polyline.axis_frames(jf)
    many = v0 + np.random.default_rng(1).normal(size=(728, 6, 1)) * u
    ms = _best_ms(lambda: collision.colliding_polylines(motions, many), repeat=5)
    print(f"thin collision check, 728 polylines batched: {ms:.1f} ms "
          f"({1e3 * ms / 728:.0f} us each)")

    loops = table1.random_loops(args.seed + 1, (args.loops + 1) // 2).reshape(-1, 6, 8)
    loops = loops[: args.loops]
    times, failures = [], 0
    for j in loops:
        t0 = time.perf_counter()
        try:
            realize.realize(j)
        except ValueError:
            failures += 1
        times.append(time.perf_counter() - t0)
    t = 1e3 * np.array(times)
    print(f"realize over {len(loops)} AS+DB loops: median {np.median(t):.1f} ms, "
          f"p95 {np.percentile(t, 95):.1f} ms, max {t.max():.1f} ms, failures {failures}")

    n = args.table_motions
    t0 = time.perf_counter()
    with batch.Runner(workers=2) as runner:
        table1.run(n, args.seed, runner.values)
    el = time.perf_counter() - t0
    print(f"validate realization --motions {n} --workers 2: {el:.1f} s "
          f"-> 1000 motions ~ {el * 1000 / n / 60:.1f} min")


if __name__ == "__main__":
    main()
