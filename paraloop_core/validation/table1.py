"""Statistical validation of the realization algorithm (paper Sec. 6.3, Table 1).

Random cubic motions: ``C = (t - h_0)(t - h_1)(t - h_2)`` with the 8 coefficients of each
``h_i`` standard normal, then ``h[4] = 0`` and the moment made orthogonal to the direction (a
rotation factor), redrawn in the rare non-generic case. Of the nine loops of each motion one
angle-symmetric and one double-Bennett loop are drawn uniformly with the same generator
(one generator per motion, seeded by ``[seed, motion]``).
Each loop is realized with ``p = 10``, ``d = l / 100``, ``rho = d / 4`` (l: initial polyline).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np

from paraloop_core.algebra import factor, poly
from paraloop_core.errors import RealizationError
from paraloop_core.linkage import loops
from paraloop_core.realization.realize import realize

KINDS = ("AS", "DB")
#: Table 1 columns: mean k, mean collision checks, mean steps back, mean min-distance
#: computations, mean length ratio, z (first offset sequence worked), s (sign sequence worked).
COLUMNS = ("k", "collision_checks", "steps_back", "min_distance_computations", "length_ratio",
           "z", "s")
PAPER = {
    "AS": (1.355, 1169.782, 0.687, 555.284, 1.416, 506, 88),
    "DB": (1.100, 928.379, 0.764, 613.044, 1.346, 590, 55),
}


def random_rotation_factors(rng: np.random.Generator, shape: tuple) -> np.ndarray:
    """Rotation factors ``(*shape, 8)``: normal coefficients, dual scalar 0, moment ⟂ direction."""
    return factor.clean_factor(rng.normal(size=shape + (8,)))


def random_loops(seed: int, n_motions: int) -> np.ndarray:
    """Joint factors ``(n_motions, 2, 6, 8)``: one AS and one DB loop per random cubic.

    Motion m uses its own generator ``default_rng([seed, m])``, so it does not depend on
    ``n_motions`` (a run of N motions is a prefix of a longer run with the same seed).
    """
    rngs = [np.random.default_rng([seed, m]) for m in range(n_motions)]
    as_idx, db_idx = np.flatnonzero(loops.LOOP_IS_AS), np.flatnonzero(~loops.LOOP_IS_AS)
    out = np.zeros((n_motions, 2, 6, 8))
    todo = np.arange(n_motions)
    while todo.size:  # redraw the (rare) non-generic motions from their own generators
        h = np.stack([random_rotation_factors(rngs[m], (3,)) for m in todo])
        facts = factor.all_factorizations_batch(poly.from_factors(h))
        jf = loops.loop_joint_factors(facts.factors)  # (m, 9, 6, 8), factorizations batched
        for row in np.flatnonzero(facts.ok):
            m = todo[row]
            out[m] = jf[row, [rngs[m].choice(as_idx), rngs[m].choice(db_idx)]]
        todo = todo[~facts.ok]
    return out


def realize_row(job: tuple[int, int, np.ndarray]) -> dict:
    """Realize one loop; ``job = (motion, kind index, joint factors)`` -> one CSV row."""
    motion, kind, jf = job
    row = {"motion": motion, "kind": KINDS[kind], "ok": False, "reason": ""}
    try:
        r = realize(jf, p=10.0, d_fraction=0.01, rho_fraction=0.25)
    except RealizationError as exc:
        row["reason"] = exc.reason
        return row
    row.update(ok=True, **{key: r.stats[key] for key in COLUMNS[:5]})
    row["offset_rank"] = r.stats["offset_rank"]
    row["collision_checks_sequential"] = r.stats["collision_checks_sequential"]
    row["min_clearance_over_rho"] = r.min_clearance / r.radius
    return row


def run(
    n_motions: int,
    seed: int,
    mapper: Callable[[Callable, Iterable], Iterable] = map,
) -> list[dict]:
    """Realize the AS and DB loop of ``n_motions`` random cubics; rows in job order.
    ``mapper(realize_row, jobs)`` runs the jobs and yields their rows in order (the command line
    passes one that spreads them over processes or a cluster). Arguments must be true integers
    (``n_motions`` >= 1, ``seed`` >= 0): ParaloopError."""
    from paraloop_core.errors import ParaloopError

    for name, value, lo in (("n_motions", n_motions, 1), ("seed", seed, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
            raise ParaloopError(f"{name} must be an integer >= {lo}, got {value!r}",
                                "bad-parameters")
    lp = random_loops(seed, n_motions)
    jobs = [(m, k, lp[m, k]) for m in range(n_motions) for k in range(len(KINDS))]
    return list(mapper(realize_row, jobs))


def summarize(rows: list[dict]) -> dict[str, dict]:
    """Per kind: Table 1 means over successful rows, z, s, successes and attempts."""
    out = {}
    for kind in KINDS:
        mine = [r for r in rows if r["kind"] == kind]
        ok = [r for r in mine if r["ok"]]
        means = {key: float(np.mean([r[key] for r in ok])) if ok else float("nan")
                 for key in COLUMNS[:5]}
        means["z"] = sum(r["offset_rank"] == 0 for r in ok)
        means["s"] = sum(r["offset_rank"] == 1 for r in ok)
        out[kind] = {"means": means, "successes": len(ok), "attempts": len(mine)}
    return out
