"""Random generic designs (``docs/design-format.md`` dicts), deterministic from a seed.

A design is drawn as: a random monic cubic ``M = (t - h_0)(t - h_1)(t - h_2)`` of rotation factors
``h = h0 + p + eps (c x p)`` (random direction, |p|, h0 and axis point c spread over orders of
magnitude), a random reference pose S, the world cubic ``C = M S``, four distinct parameters
``t_i`` (possibly one at infinity), poses ``C(t_i)`` as position + ``wxyz`` (in random order),
then a random family, mu (or ``"inf"``) and loop. ``scale`` multiplies every position (units).
"""

from __future__ import annotations

import numpy as np

from . import dq8


def _spread(rng: np.random.Generator, lo: float, hi: float, size=None) -> np.ndarray:
    """Log-uniform magnitudes in ``[10^lo, 10^hi]``."""
    return 10.0 ** rng.uniform(lo, hi, size)


def random_factor(rng: np.random.Generator) -> np.ndarray:
    """A random rotation factor ``h`` ``(8,)``: dual scalar 0, moment ``c x p`` orthogonal to p."""
    p = rng.normal(size=3)
    p *= _spread(rng, -1.0, 1.0) / np.linalg.norm(p)
    c = rng.normal(size=3) * _spread(rng, -1.0, 1.0)
    h0 = rng.normal() * _spread(rng, -1.0, 1.0)
    return np.concatenate([[h0], p, [0.0], np.cross(c, p)])


def random_pose(rng: np.random.Generator) -> np.ndarray:
    """A random unit pose ``(8,)``."""
    return dq8.pose_from_pos_wxyz(rng.normal(size=3) * _spread(rng, -1.0, 1.0), rng.normal(size=4))


def _evaluate(c: np.ndarray, t: float) -> np.ndarray:
    """``C(t)`` ``(8,)`` of ``c`` ``(n+1, 8)``; ``t = inf`` gives the leading coefficient."""
    if np.isinf(t):
        return c[-1].copy()
    return sum(ck * t**k for k, ck in enumerate(c))


def random_design(seed: int, scale: float = 1.0, realization: bool = True) -> dict:
    """A random generic four-pose design dict from ``seed`` (positions times ``scale``)."""
    rng = np.random.default_rng([seed, 13])
    hs = np.array([random_factor(rng) for _ in range(3)])
    world = dq8.poly_mul(dq8.from_factors(hs), random_pose(rng)[None])  # (4, 8)
    t_scale = float(np.median(np.linalg.norm(hs[:, 1:4], axis=1)))
    t_mid = float(np.median(hs[:, 0]))
    ts = list(t_mid + t_scale * rng.normal(size=4) * 2.0)
    if rng.random() < 0.3:
        ts[0] = np.inf
    order = rng.permutation(4)
    poses = []
    for i in order:
        pos, wxyz = dq8.pos_wxyz(_evaluate(world, ts[i]))
        poses.append({"position": (pos * scale).tolist(), "wxyz": wxyz.tolist()})
    mu = "inf" if rng.random() < 0.2 else float(rng.normal() * _spread(rng, -1.0, 1.0))
    design = {
        "format": "paraloop-design",
        "version": 1,
        "name": f"generic-{seed}-x{scale:g}",
        "poses": poses,
        "motion": {"method": "four-pose", "family": int(rng.integers(2)), "mu": mu,
                   "criterion": None},
        "loop": int(rng.integers(9)),
        "realization": {"p": 10, "d_fraction": 0.01, "rho_fraction": 0.25}
        if realization else None,
    }
    return design


def random_designs(n: int, start: int = 0, scale: float = 1.0) -> list[dict]:
    """Designs of seeds ``start .. start + n - 1``."""
    return [random_design(s, scale) for s in range(start, start + n)]
