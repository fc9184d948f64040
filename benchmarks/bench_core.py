"""Kinematic-core speed (issue 2): factorizations batched and single, and a full design solve.

Run: ``.venv/bin/python benchmarks/bench_core.py``. Prints figures; asserts nothing.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from independent.generic_designs import random_design  # noqa: E402

from paraloop_core import design, pipeline
from paraloop_core.algebra import dq, factor, poly
from paraloop_core.linkage import singularity
from paraloop_core.motion import fourpose
from paraloop_core.validation import table1


def _timeit(fn, repeat: int) -> np.ndarray:
    out = np.empty(repeat)
    for k in range(repeat):
        t0 = time.perf_counter()
        fn()
        out[k] = time.perf_counter() - t0
    return out


def random_cubics(n: int, seed: int = 0) -> np.ndarray:
    return poly.from_factors(table1.random_rotation_factors(np.random.default_rng(seed), (n, 3)))


def main() -> None:
    cubics = random_cubics(10_000)
    factor.all_factorizations_batch(cubics[:10])  # warm-up
    batch = _timeit(lambda: factor.all_factorizations_batch(cubics), 5)
    facts = factor.all_factorizations_batch(cubics)
    err = np.abs(poly.from_factors(facts.factors) - cubics[:, None]).max(axis=(-3, -2, -1))
    print(f"six factorizations, batch of 10,000: {batch.min() * 1e3:.1f} ms total, "
          f"{batch.min() / 1e4 * 1e3:.4f} ms per motion; generic {facts.ok.mean():.4f}; "
          f"max rel. product error {np.max(err / np.abs(cubics).max(axis=(-2, -1))):.1e}")
    single = _timeit(lambda: factor.all_factorizations(cubics[0]), 300)
    print(f"six factorizations, one call: median {np.median(single) * 1e3:.3f} ms")
    hss = _timeit(lambda: factor.factorize(cubics[0]), 300)
    print(f"one HSS factorization, one call: median {np.median(hss) * 1e3:.3f} ms")

    path = Path(__file__).resolve().parents[1] / "assets" / "designs" / "tv8.json"
    d = design.load_design(path)
    jf = np.stack([lp.joint_factors for lp in pipeline.solve(d, realize=False).loops])
    unit = pipeline.unit_length(pipeline.design_poses(d))
    sing = _timeit(lambda: singularity.singularity_min(jf, length=unit), 200)
    print(f"singularity minimum of the nine loops ({path.name}): "
          f"median {np.median(sing) * 1e3:.2f} ms")
    poses = pipeline.design_poses(d)
    c_rel = pipeline._four_pose(d, dq.scale_lengths(poses, 1.0 / unit), unit)[0]
    monic = fourpose.world_motion(poses[0], dq.scale_lengths(c_rel, unit))
    stages = {
        "four-pose": lambda: pipeline._four_pose(d, dq.scale_lengths(poses, 1.0 / unit), unit),
        "six factorizations": lambda: factor.all_factorizations(monic),
        "singularity": lambda: singularity.singularity_min(jf, length=unit),
    }
    print("per stage (" + path.name + "): " + ", ".join(
        f"{name} {np.median(_timeit(fn, 200)) * 1e3:.2f} ms" for name, fn in stages.items()))
    full = _timeit(lambda: pipeline.solve(d, realize=False), 200)
    print(f"four-pose + six factorizations + nine loops + singularity ({path.name}): "
          f"median {np.median(full) * 1e3:.2f} ms, p95 {np.percentile(full, 95) * 1e3:.2f} ms")
    # the same chain on designs nobody picked (best of 3 per design: the machine's noise out)
    generic = [design.design_from_dict(random_design(s, 1.0)) for s in range(4000, 4200)]
    per = np.array([_timeit(lambda g=g: pipeline.solve(g, realize=False), 3).min()
                    for g in generic]) * 1e3
    print(f"the same over 200 random generic designs: median {np.median(per):.2f} ms, p90 "
          f"{np.percentile(per, 90):.2f} ms, p95 {np.percentile(per, 95):.2f} ms, max "
          f"{per.max():.1f} ms, <= 3 ms: {np.mean(per <= 3.0):.0%}")


if __name__ == "__main__":
    main()
