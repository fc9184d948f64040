"""Statistical validation of the evolution (paper Sec. 6.3, Fig. 16).

Setup as in the paper: one random cubic target motion; the metric of an inertia sphere of radius
1 centred at the origin (the barycenter); translations scaled so that the barycenter's
trajectory under the target motion has length 20; ``targets`` ordered poses sampled from it
(S_0 = C(inf), the others equally spaced in metric arc length round the cycle); many random
starts (eq. 9). Per iteration: mean, best and worst cost (summed squared metric distances of the
targets to their closest poses, w = 1) over all starts; a finished start keeps its last cost.
"""

from __future__ import annotations

import csv
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from paraloop_core.algebra import dq, factor, poly
from paraloop_core.motion import closest, evolution, metric

#: The paper's barycenter trajectory length and inertia-sphere radius.
TRAJECTORY_LENGTH = 20.0
RADIUS = 1.0


@dataclass(frozen=True)
class Fig16Run:
    """``motion`` ``(4, 8)`` target cubic; ``targets`` ``(m, 8)``; ``costs`` ``(starts, n)``
    cost per iteration (padded with the last value); ``status`` per start; ``best`` / ``worst``
    start index by final cost; ``seconds`` wall time of the starts."""

    motion: np.ndarray
    targets: np.ndarray
    costs: np.ndarray
    status: tuple[str, ...]
    best: int
    worst: int
    seconds: float

    @property
    def mean(self) -> np.ndarray:
        return self.costs.mean(axis=0)


def target_motion(rng: np.random.Generator, length: float = TRAJECTORY_LENGTH) -> np.ndarray:
    """Random monic cubic ``(4, 8)`` whose origin trajectory (one cycle) has the given length.

    Scaling all dual parts by s keeps the Study condition and scales every translation by s.
    """
    p = rng.normal(size=(3, 3))
    m = rng.normal(size=(3, 3))
    h = factor.clean_factor(np.concatenate([rng.normal(size=(3, 1)), p, np.zeros((3, 1)), m], 1))
    c = poly.from_factors(h)
    x = dq.translation_of(poly.evaluate_pose(c, poly.param_to_t(np.linspace(0, 1, 8193))))
    scale = length / np.sum(np.linalg.norm(np.diff(x, axis=0), axis=-1))
    return c * np.r_[np.ones(4), np.full(4, scale)]


def sample_targets(c: np.ndarray, count: int, inertia: metric.Inertia) -> np.ndarray:
    """``count`` unit poses ``(count, 8)`` on ``c``: C(inf), then equal metric arc steps."""
    u, s = closest.arc_table(c, inertia, 8192)
    uk = np.interp(s[-1] * np.arange(count) / count, s, u)
    return dq.normalize(poly.evaluate_pose(c, poly.param_to_t(uk)))


def run(starts: int = 500, targets: int = 10, seed: int = 0, workers: int = 1,
        max_iterations: int = 100,
        progress: Callable[[float, str], None] | None = None,
        mapper: Callable[[Callable, Iterable], Iterable] | None = None) -> Fig16Run:
    """Run the Fig. 16 experiment (all starts); see the module docstring. ``workers`` and
    ``mapper``: as in :func:`evolution.evolve_starts`. Arguments must be true integers
    (``targets`` >= 5, ``seed`` >= 0, the others >= 1): ParaloopError."""
    from paraloop_core.errors import ParaloopError

    for name, value, lo in (("starts", starts, 1), ("targets", targets, 5), ("seed", seed, 0),
                            ("workers", workers, 1), ("max_iterations", max_iterations, 1)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
            raise ParaloopError(f"{name} must be an integer >= {lo}, got {value!r}",
                                "bad-parameters")
    inertia = metric.sphere(RADIUS)
    c = target_motion(np.random.default_rng(seed))
    poses = sample_targets(c, targets, inertia)
    settings = evolution.EvolutionSettings(starts=starts, seed=seed, workers=workers,
                                           max_iterations=max_iterations)
    t0 = time.perf_counter()
    _, results = evolution.evolve_starts(poses, inertia, settings, progress, mapper=mapper)
    seconds = time.perf_counter() - t0
    n = max(len(r.cost_history) for r in results)
    costs = np.array([np.pad(r.cost_history, (0, n - len(r.cost_history)), mode="edge")
                      for r in results])
    final = costs[:, -1]
    return Fig16Run(c, poses, costs, tuple(r.status for r in results), int(np.argmin(final)),
                    int(np.argmax(final)), seconds)


def write_csv(res: Fig16Run, path: Path) -> None:
    """One row per iteration: mean, best-run, worst-run, minimum, median, maximum cost."""
    c = res.costs
    with Path(path).open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["iteration", "mean", "best_run", "worst_run", "min", "median", "max"])
        for i in range(c.shape[1]):
            col = c[:, i]
            w.writerow([i, *(f"{v:.6e}" for v in (col.mean(), c[res.best, i], c[res.worst, i],
                                                    col.min(), np.median(col), col.max()))])


def plot(res: Fig16Run, path: Path, iterations: int | None = None) -> None:
    """Fig. 16 style PNG: mean (green), best run (red), worst run (blue), all runs (grey)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = res.costs.shape[1] if iterations is None else min(iterations, res.costs.shape[1])
    it = np.arange(n)
    floor = 1e-30  # exact fits reach round-off; keep them on the log axis
    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=120)
    ax.plot(it, np.maximum(res.costs[:, :n], floor).T, color="0.6", lw=0.4, alpha=0.25)
    ax.plot(it, np.maximum(res.mean[:n], floor), color="green", lw=2, label="mean")
    ax.plot(it, np.maximum(res.costs[res.best, :n], floor), color="red", lw=2,
            label=f"best run (start {res.best})")
    ax.plot(it, np.maximum(res.costs[res.worst, :n], floor), color="blue", lw=2,
            label=f"worst run (start {res.worst})")
    ax.set_yscale("log")
    ax.set_xlabel("iteration")
    ax.set_ylabel("sum of squared distances (eq. 8)")
    ax.set_title(f"Evolution of {len(res.costs)} random starts, {len(res.targets)} targets")
    ax.legend(loc="lower left", fontsize=8)
    ax.grid(True, which="major", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
