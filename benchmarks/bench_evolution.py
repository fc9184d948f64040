"""Benchmark of the motion evolution (prints figures; no timed asserts).

    .venv/bin/python benchmarks/bench_evolution.py [--starts 40] [--workers 2]

* closest poses (degree <= 10 polynomial, one batched companion-matrix call) for 9 and 1000
  targets;
* one start on 10 targets (four-pose start and random starts): wall time and iterations;
* the Fig. 16 setup with ``--starts`` random starts, extrapolated to 500 starts.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from paraloop_core.motion import closest, evolution, metric
from paraloop_core.motion import evolution_stages as stages
from paraloop_core.validation import fig16


def timed(fn, repeat: int = 1):
    t0 = time.perf_counter()
    for _ in range(repeat):
        out = fn()
    return (time.perf_counter() - t0) / repeat, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=40)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()

    inertia = metric.sphere(1.0)
    c = fig16.target_motion(np.random.default_rng(0))
    targets = fig16.sample_targets(c, 10, inertia)
    many = fig16.sample_targets(c, 1000, inertia)
    for name, s in (("9 targets", targets[1:]), ("1000 targets", many)):
        dt, _ = timed(lambda s=s: closest.closest_pose(c, s, inertia), 20)
        print(f"closest_pose, {name:>12}: {dt * 1e3:7.2f} ms")

    settings = evolution.EvolutionSettings(starts=1, init="four-pose")
    dt, res = timed(lambda: evolution.fit_motion(targets, inertia, settings))
    print(f"one four-pose start, 10 targets: {dt:.3f} s, {len(res.cost_history) - 1} "
          f"iterations, cost {res.cost:.2e} ({res.status})")

    prob = stages.Problem(targets, targets, np.arange(10), inertia, 1.0)
    times, iters, ok = [], [], 0
    for i in range(10):
        r = np.random.default_rng([0, i]).normal(size=(3, 4))
        dt, res = timed(lambda r=r, i=i: stages.evolve_start(
            prob, evolution.EvolutionSettings(), np.c_[r, np.zeros((3, 4))], i))
        times.append(dt)
        iters.append(len(res.cost_history) - 1)
        ok += res.cost_history[-1] <= 1e-8
    per_it = sum(times) / max(sum(iters), 1)
    print(f"one random start, 10 targets: mean {np.mean(times):.3f} s, max {max(times):.3f} s, "
          f"mean {np.mean(iters):.0f} iterations ({per_it * 1e3:.1f} ms/iteration), "
          f"{ok}/10 exact")

    run = fig16.run(args.starts, 10, 0, args.workers)
    est = run.seconds * 500 / args.starts
    print(f"Fig. 16 setup: {args.starts} starts in {run.seconds:.1f} s with {args.workers} "
          f"worker(s) -> 500 starts ~ {est:.0f} s ({est / 60:.1f} min); "
          f"{int(np.sum(run.costs[:, -1] <= 1e-8))}/{args.starts} exact")


if __name__ == "__main__":
    main()
