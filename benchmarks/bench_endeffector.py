"""Benchmark: realization with a 100-face end-effector (paper Sec. 5.1) on random loops.

Prints figures, never asserts timings. P is a closed disc with 25 sides (100 triangles) of
radius ``0.04 l`` centred between ``V_2`` and ``V_3`` of the initial polyline (body axes =
world axes); each AS and DB loop of ``--motions`` random cubics (``table1.random_loops``) is
realized with the defaults of :func:`realize_ee.realize_with_effector` and ``--max-k``.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/bench_endeffector.py --motions 50
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from paraloop_core.algebra import dq
from paraloop_core.errors import RealizationError
from paraloop_core.realization import endeffector as eem
from paraloop_core.realization import realize_ee as ree
from paraloop_core.realization.polyline import polyline_length, shortest_polyline
from paraloop_core.realization.realize import realize
from paraloop_core.validation.table1 import random_loops


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--motions", type=int, default=50, help="random cubics (2 loops each)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-k", type=int, default=10)
    ap.add_argument("--no-base", action="store_true", help="skip timing realize() alone")
    args = ap.parse_args()
    jfs = random_loops(args.seed, args.motions).reshape(-1, 6, 8)
    disc = eem.disc(1.0, 0.05, segments=25)
    ee_times, base_times, fails, ks = [], [], 0, []
    for jf in jfs:
        _, v0 = shortest_polyline(jf)
        length = float(polyline_length(v0))
        body = eem.scaled(disc, 0.04 * length)
        t0 = time.perf_counter()
        ee = eem.attach(body, dq.translation(0.5 * (v0[2] + v0[3])), jf)
        try:
            r = ree.realize_with_effector(jf, ee, max_k=args.max_k)
            ks.append(r.realization.stats["k"])
        except RealizationError:
            fails += 1
        ee_times.append(time.perf_counter() - t0)
        if not args.no_base:
            t0 = time.perf_counter()
            try:
                realize(jf)
            except RealizationError:
                pass
            base_times.append(time.perf_counter() - t0)
    ms = 1e3 * np.array(ee_times)
    print(f"loops: {len(jfs)} (P: {len(disc.faces)} faces), realized: {len(jfs) - fails}, "
          f"cap reached (k > {args.max_k}): {fails}, mean k: {np.mean(ks):.2f}")
    print(f"realize_with_effector: median {np.median(ms):.1f} ms, p90 "
          f"{np.percentile(ms, 90):.1f} ms, max {ms.max():.1f} ms (failures included)")
    if base_times:
        bms = 1e3 * np.array(base_times)
        print(f"realize (bars only, same loops): median {np.median(bms):.1f} ms, p90 "
              f"{np.percentile(bms, 90):.1f} ms")


if __name__ == "__main__":
    main()
