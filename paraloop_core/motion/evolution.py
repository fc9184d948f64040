"""Motion evolution: fit a rational cubic motion to many ordered target poses (paper Sec. 4.3).

Frames: the targets are moved to the frame of the first one (``p_i = S_0^-1 S_i``, ``p_0 = 1``).
The fitted ``motion_rel`` ``C = (t - h_1)(t - h_2)(t - h_3)`` is monic, so ``C(inf) = 1`` hits
S_0 exactly, and the world motion is ``reference * C(t)`` with ``reference = S_0``. With the
free reference frame (final stage only) the fitted motion is ``X C(t)``; ``motion_rel`` stays the
monic ``C`` and ``reference = S_0 X`` (unit), so always world motion = reference * motion_rel.

Multi-start: start 0 is the four-pose interpolant (``init='four-pose'``) or random; every other
start is random (eq. 9, seeded by ``(seed, index)``, so results do not depend on ``workers``).
The per-start stage machine lives in :mod:`.evolution_stages`.
"""

from __future__ import annotations

import contextlib
import functools
import multiprocessing
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace

import numpy as np

from paraloop_core.algebra import dq, factor, poly
from paraloop_core.errors import FitError, InterpolationError
from paraloop_core.motion import closest, fourpose, metric, selection
from paraloop_core.motion.evolution_stages import (
    EvolutionSettings,
    Problem,
    StartResult,
    cyclic_order,
    evolve_start,
)
from paraloop_core.tolerance import TOL

__all__ = ["EvolutionSettings", "FitResult", "evolve_starts", "fit_motion", "fit_result_to_dict"]


@dataclass(frozen=True)
class FitResult:
    """A fitted motion. ``motion_rel`` ``(4, 8)`` monic cubic, world motion
    ``reference * motion_rel(t)``; ``reference`` ``(8,)`` unit (S_0, or S_0 X with the free
    frame); per target ``closest_t`` ``(m,)`` (``inf`` for S_0 unless the frame is free) and
    metric ``distances`` ``(m,)`` (the given inertia); ``cost`` = summed squared distances;
    ``cost_history`` / ``stage_history`` of the winning start; ``loops``: gaps i (targets
    i -> i+1) still showing the loop phenomenon; ``loop_fixed``: the modified procedure ran;
    ``factors`` ``(3, 8)`` of ``motion_rel`` (a warm start for a nearby fit)."""

    motion_rel: np.ndarray
    reference: np.ndarray
    closest_t: np.ndarray
    distances: np.ndarray
    cost: float
    cost_history: list[float]
    stage_history: list[str]
    winning_start: int
    starts_tried: int
    status: str
    loops: tuple[int, ...]
    loop_fixed: bool
    factors: np.ndarray


def check_targets(targets: np.ndarray, inertia: metric.Inertia) -> np.ndarray:
    """Validate world target poses ``(m, 8)``; return them unit and Study-projected.

    Raises :class:`FitError` (``too-few-poses``, ``not-finite``, ``duplicate-poses``).
    """
    s = np.asarray(targets, dtype=np.float64)
    if s.ndim != 2 or s.shape[1] != 8:
        raise ValueError(f"targets must have shape (m, 8), got {s.shape}")
    if len(s) < 5:
        raise FitError(f"motion evolution needs at least 5 target poses, got {len(s)} "
                       "(use four-pose interpolation for 4)", "too-few-poses")
    bad = np.flatnonzero(~np.all(np.isfinite(s), axis=1))
    if bad.size:
        raise FitError(f"target pose {int(bad[0])} has non-finite entries", "not-finite")
    pn = np.linalg.norm(s[:, :4], axis=1)
    if np.any(pn <= TOL.zero * (1.0 + np.linalg.norm(s[:, 4:], axis=1))):
        raise ValueError(f"target pose {int(np.argmin(pn))} has a zero primal part (not a pose)")
    s = dq.study_project(dq.normalize(s))
    d = np.sqrt(metric.distance_sq(s[:, None], s[None], inertia))
    i, j = np.nonzero(np.triu(d <= TOL.duplicate * (1.0 + d.max()), 1))
    if i.size:
        raise FitError(f"target poses {int(i[0])} and {int(j[0])} coincide: every target must "
                       "be a distinct pose", "duplicate-poses")
    return s


def interpolate_poses(a: np.ndarray, b: np.ndarray, lam: np.ndarray,
                      inertia: metric.Inertia) -> np.ndarray:
    """Metric-aware interpolation (PHR04/HP04): the unit pose ``(..., 8)`` whose ellipsoid
    vertices best fit ``(1 - lam) a(v) + lam b(v)`` (least squares = eq. 8, Kabsch).
    ``a``, ``b`` ``(..., 8)``, ``lam`` ``(...)``, broadcasting."""
    v = inertia.vertices  # (6, 3) body points (weighted as in the metric)
    lam = np.asarray(lam, dtype=np.float64)[..., None, None]
    x = (1.0 - lam) * dq.transform_points(a[..., None, :], v) + lam * dq.transform_points(
        b[..., None, :], v)
    vc, xc = v - v.mean(0), x - x.mean(-2, keepdims=True)
    u, _, vt = np.linalg.svd(np.swapaxes(xc, -1, -2) @ vc)
    sign = np.sign(np.linalg.det(u @ vt))
    u[..., :, 2] *= sign[..., None]
    rot = u @ vt
    trans = x.mean(-2) - (rot @ v.mean(0)[:, None])[..., 0]
    mat = np.concatenate([rot, trans[..., None]], axis=-1)
    return dq.from_matrix(mat)


def with_virtual_targets(targets: np.ndarray, inertia: metric.Inertia,
                         count: int) -> tuple[np.ndarray, np.ndarray]:
    """Insert ``count`` virtual poses between adjacent targets ``(m, 8)`` (closing gap
    excluded). Returns ``(guides (m + (m-1) count, 8), real (m,))``."""
    lam = np.arange(1, count + 1) / (count + 1.0)
    mid = interpolate_poses(targets[:-1, None], targets[1:, None], lam, inertia)  # (m-1, c, 8)
    rows = np.concatenate([targets[:-1, None], mid], axis=1).reshape(-1, 8)
    guides = np.concatenate([rows, targets[-1:]], axis=0)
    return guides, np.arange(len(targets)) * (count + 1)


def four_pose_guess(prob: Problem, world: np.ndarray, indices: tuple[int, ...],
                    ordered: bool = True) -> np.ndarray:
    """Factors ``(3, 8)`` of the four-pose interpolant of ``world[indices]`` closest to all
    targets (summed squared distances; among those visiting the targets in order when
    ``ordered`` and any do). Both families; mu scanned over the projective line (``u`` grid),
    then twice refined around the best ``u`` of each family."""
    fams = fourpose.four_pose_families(world[list(indices)])
    best_h, best_cost = None, np.inf
    for f in range(len(fams.c)):
        lo, hi = 0.0, 1.0
        for _ in range(3):  # coarse scan, then two zooms around the best u
            u = np.linspace(lo, hi, 130)[1:-1]
            mus = poly.param_to_t(u)
            keep = ~fourpose.bad_mu_mask(fams, f, mus)
            if not keep.any():  # every scanned mu degenerate: try the other family
                break
            h, cost = _score_interpolants(prob, fourpose.four_pose_motion_batch(
                fams, f, mus[keep]), ordered)
            k = int(np.argmin(cost))
            if cost[k] < best_cost:
                best_h, best_cost = h[k], cost[k]
            width = 2.0 * (hi - lo) / 129.0
            lo, hi = u[keep][k] - width, u[keep][k] + width
    if best_h is None:
        raise InterpolationError("four-pose initial guess: no interpolant of the chosen poses is "
                                 "generic (factorizable); choose other four_pose_indices", "rank")
    return best_h


def _score_interpolants(prob: Problem, c: np.ndarray, ordered: bool):
    """Factors ``(K, 3, 8)`` and cost ``(K,)`` of candidate cubics ``(K, 4, 8)``: summed squared
    closest distances, inf where not factorizable (or, if any is, not in order)."""
    t, d2 = closest.closest_pose(c[:, None], prob.targets[None, 1:], prob.inertia, robust=False)
    h, code = factor.hss_batch(c)
    cost = np.where(code == 0, np.sum(d2, -1), np.inf)
    if ordered:
        in_order = cyclic_order(np.concatenate([np.full((len(t), 1), np.inf), t], -1)) != 0
        cost = np.where(in_order, cost, cost + np.where(np.any(in_order), np.inf, 0.0))
    return h, cost


def _run_chunk(prob: Problem, fix: Problem | None, settings: EvolutionSettings,
               indices: list[int], first: np.ndarray | None) -> list[StartResult]:
    """Worker: run the starts ``indices``; a start showing a loop reruns with the fix."""
    out = []
    for i in indices:
        if i == 0 and first is not None:
            h0 = first
        else:
            r = np.random.default_rng([settings.seed, i]).normal(size=(3, 4))
            h0 = np.concatenate([r, np.zeros((3, 4))], axis=1)  # spherical start, eq. 9
        res = evolve_start(prob, settings, h0, i)
        if res.loops and fix is not None:
            res = _straighten(prob, fix, settings, res)
        out.append(res)
    return out


def _straighten(prob: Problem, fix: Problem, settings: EvolutionSettings,
                res: StartResult) -> StartResult:
    """Loop phenomenon (Fig. 17): run the modified procedure (virtual targets, guides (2b) in
    every stage, bounded steps) from the looped motion, then polish with the normal procedure.
    Returns the best loop-free of (polished, straightened), else ``res``; histories are joined."""
    fixed = evolve_start(fix, settings, res.factors, res.index, loop_fix=True)
    polished = evolve_start(prob, settings, fixed.factors, res.index)
    for cand, parts in ((polished, (res, fixed, polished)), (fixed, (res, fixed))):
        if cand.status in ("converged", "stalled") and not cand.loops:
            names = [("loop-fix" if p is fixed else s) for p in parts for s in p.stage_history]
            return replace(
                cand, cost_history=sum((p.cost_history for p in parts), ()),
                stage_history=tuple(names), steps=sum((p.steps for p in parts), ()),
                loop_fixed=True)
    return res


def evolve_starts(
    targets: np.ndarray, inertia: metric.Inertia, settings: EvolutionSettings,
    progress: Callable[[float, str], None] | None = None, initial: np.ndarray | None = None,
    mapper: Callable[[Callable, Iterable], Iterable] | None = None,
) -> tuple[np.ndarray, list[StartResult]]:
    """Run all starts (start 0 from the factors ``initial`` ``(3, 8)`` when given); returns
    ``(world targets (m, 8) unit, results by start index)``. ``mapper(run, chunks)`` runs the
    chunks of start indices and yields their results in order (default: in this process, or a
    pool of ``settings.workers`` processes; the command line passes its own)."""
    world = check_targets(targets, inertia)
    rel = dq.normalize(dq.mul(dq.conj(world[0]), world))
    rel[0] = dq.IDENTITY
    prob = Problem(rel, rel, np.arange(len(rel)), inertia, cost_scale(rel, inertia))
    fix = None
    if settings.loop_fix and settings.ordered:
        guides, real = with_virtual_targets(rel, inertia, settings.virtual)
        fix = Problem(rel, guides, real, inertia, prob.scale)
    first = None if initial is None else np.asarray(initial, float).reshape(3, 8)
    if first is None and settings.init == "four-pose":
        m = len(rel)
        idx = settings.four_pose_indices or tuple(int(round(k * m / 4.0)) for k in range(4))
        if max(idx) >= m:
            raise FitError(f"four_pose_indices {idx} out of range for {m} targets",
                           "bad-parameters")
        first = four_pose_guess(prob, world, idx, settings.ordered)
    n, workers = settings.starts, settings.workers
    if multiprocessing.current_process().daemon:
        # a worker of a pool or of a Dask cluster may not start processes: run the starts here
        # (results do not depend on workers)
        workers = 1
    # one start per call in one process (progress per start); else small chunks: smooth
    # progress, fair load
    size = 1 if workers == 1 else max(1, min(10, n // (8 * workers)))
    chunks = [list(range(k, min(k + size, n))) for k in range(0, n, size)]
    results: list[StartResult] = []

    def report(done: list[StartResult]) -> None:
        results.extend(done)
        if progress is not None:
            best = min((r.cost_history[-1] for r in results if r.cost_history), default=np.nan)
            progress(len(results) / n, f"{len(results)}/{n} starts, best cost {best:.3g}")

    with contextlib.ExitStack() as stack:
        if mapper is None:
            mapper = map if workers == 1 else stack.enter_context(
                ProcessPoolExecutor(max_workers=workers)).map
        for done in mapper(functools.partial(_run_chunk, prob, fix, settings, first=first),
                           chunks):
            report(done)
    return world, sorted(results, key=lambda r: r.index)


def cost_scale(rel: np.ndarray, inertia: metric.Inertia) -> float:
    """Summed squared metric chords of consecutive targets ``(m, 8)``, the closing one
    included: the scale of a fit's cost."""
    return float(np.sum(metric.distance_sq(rel, np.roll(rel, -1, axis=0), inertia)))


def best_start(results: list[StartResult], smooth_drive: float = 0.0,
               scale: float = 1.0) -> StartResult | None:
    """The best converged or stalled start, loop-free ones first; None if none. Ranked by final
    cost, or for ``smooth_drive`` w > 0 by ``cost / scale + w ln(penalty)``, penalty = the
    smooth-drive penalty of the start's cubic (best motor, the same for all nine loops;
    :func:`selection.smooth_drive_scores`, inf if not generic), ties by cost."""
    if not (np.isfinite(smooth_drive) and smooth_drive >= 0 and np.isfinite(scale) and scale > 0):
        raise ValueError(f"need smooth_drive >= 0 and scale > 0, got {smooth_drive!r}, {scale!r}")
    usable = [r for r in results if r.status in ("converged", "stalled")]
    for pool in ([r for r in usable if not r.loops], usable):
        if not pool:
            continue
        if smooth_drive == 0:
            return min(pool, key=lambda r: r.cost_history[-1])
        pen, _ = selection.smooth_drive_scores(
            np.stack([poly.from_factors(r.factors) for r in pool]))
        cost = np.array([r.cost_history[-1] for r in pool])
        return pool[int(np.lexsort((cost, cost / scale + smooth_drive * np.log(pen)))[0])]
    return None


def fit_motion(
    targets: np.ndarray, inertia: metric.Inertia, settings: EvolutionSettings | None = None,
    progress: Callable[[float, str], None] | None = None, initial: np.ndarray | None = None,
) -> FitResult:
    """Fit a rational cubic motion to world target poses ``(m, 8)`` (m >= 5, ordered unless
    ``settings.ordered`` is False; ``targets[0]`` = S_0 is hit exactly unless the frame is free).
    ``initial``: factors ``(3, 8)`` of a nearby fit (``FitResult.factors``) for start 0.

    Raises :class:`FitError` (``too-few-poses``, ``duplicate-poses``, ``not-finite``,
    ``no-convergence``).
    """
    settings = settings or EvolutionSettings()
    world, results = evolve_starts(targets, inertia, settings, progress, initial)
    rel = dq.normalize(dq.mul(dq.conj(world[0]), world))
    best = best_start(results, settings.smooth_drive, cost_scale(rel, inertia))
    if best is None:
        counts = {s: sum(r.status == s for r in results) for s in ("unordered", "degenerate")}
        raise FitError(
            f"no start of {len(results)} converged ({counts['unordered']} never visited the "
            f"targets in order, {counts['degenerate']} degenerated); try more starts, more "
            "iterations, init='four-pose' or ordered=False", "no-convergence")
    c = evolve_motion(best)
    t, d2 = closest.closest_pose(c, rel, inertia)
    if not settings.free_reference:
        t[0], d2[0] = np.inf, 0.0
    return FitResult(
        motion_rel=poly.from_factors(best.factors),
        reference=dq.normalize(dq.mul(world[0], best.frame)),
        closest_t=t, distances=np.sqrt(np.maximum(d2, 0.0)), cost=float(np.sum(d2)),
        cost_history=list(best.cost_history), stage_history=list(best.stage_history),
        winning_start=best.index, starts_tried=len(results), status=best.status,
        loops=best.loops, loop_fixed=best.loop_fixed, factors=np.array(best.factors),
    )


def evolve_motion(res: StartResult) -> np.ndarray:
    """The fitted cubic ``X C`` ``(4, 8)`` of a start in the S_0 frame."""
    return dq.mul(res.frame[None], poly.from_factors(res.factors))


def evolution_settings(options: dict) -> EvolutionSettings:
    """Settings from a design file's ``evolution`` object. Every field must have its JSON type
    and lie in its documented range (``docs/design-format.md``); otherwise DesignFileError (a
    ValueError) names the field (``field``) and the accepted range. The iteration budget
    ``starts * max_iterations`` is capped at 100000 (the time cap of a fit: about 10 ms per
    iteration with 8 poses, so at most about 15 minutes)."""
    from paraloop_core.errors import DesignFileError, shown, shown_key

    numbers = {"w0": (1.0, 1e6, False), "q": (0.0, 1.0, True), "tol": (1e-15, 1.0, False),
               "loop_ratio": (1.0, 1e6, True), "smooth_drive": (0.0, 1e6, False)}
    integers = {"max_iterations": (1, 10_000), "starts": (1, 1000), "seed": (0, 2**32 - 1),
                "workers": (1, 256), "virtual": (1, 100)}
    flags = ("free_reference", "ordered", "loop_fix", "move_guides")
    allowed = {*numbers, *integers, *flags, "init", "four_pose_indices"}
    if not isinstance(options, dict):
        raise DesignFileError("evolution", "must be an object")
    unknown = sorted((k for k in options if k not in allowed), key=str)
    if unknown:
        raise DesignFileError(shown_key(unknown[0]), f"unknown key {shown(unknown[0])} at "
                              "evolution "
                              f"(allowed: {', '.join(sorted(allowed))})")

    opts = dict(options)
    for name, (lo, hi, open_lo) in numbers.items():
        v = opts.get(name)
        if name in opts and (isinstance(v, bool) or not isinstance(v, (int, float))
                             or (isinstance(v, float) and v != v)  # NaN; ints compare exactly
                             or (v <= lo if open_lo else v < lo)
                             or (v >= hi if name == "q" else v > hi)):
            bracket = "(" if open_lo else "["
            close = ")" if name == "q" else "]"
            raise DesignFileError(name, f"must be a number in {bracket}{lo:g}, {hi:g}{close}, "
                                  f"got {shown(v)}")
    for name, (lo, hi) in integers.items():
        v = opts.get(name)
        if name in opts and (isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi):
            raise DesignFileError(name, f"must be an integer in {lo}..{hi}, got {shown(v)}")
    for name in flags:
        if name in opts and not isinstance(opts[name], bool):
            raise DesignFileError(name, f"must be true or false, got {shown(opts[name])}")
    if "init" in opts and opts["init"] not in ("random", "four-pose"):
        raise DesignFileError("init", "must be \"random\" or \"four-pose\", got "
                              f"{shown(opts['init'])}")
    idx = opts.get("four_pose_indices")
    if idx is not None:
        if (not isinstance(idx, (list, tuple)) or len(idx) != 4
                or any(isinstance(i, bool) or not isinstance(i, int) or not 0 <= i < 1000
                       for i in idx) or idx[0] != 0 or len(set(idx)) != 4):
            raise DesignFileError("four_pose_indices", "must be null or 4 distinct pose "
                                  f"indices (0..999) starting with 0, got {shown(idx)}")
        opts["four_pose_indices"] = tuple(int(i) for i in idx)
    budget = opts.get("starts", 20) * opts.get("max_iterations", 100)
    if budget > 100_000:
        raise DesignFileError("max_iterations", "starts * max_iterations must be <= 100000 "
                              f"(the iteration budget of a fit), got {budget}")
    return EvolutionSettings(**opts)


def fit_result_to_dict(r: FitResult) -> dict:
    """JSON-ready dict of a :class:`FitResult` (``closest_t`` null means t = inf)."""
    return {
        "motion_rel": r.motion_rel.tolist(),
        "reference": r.reference.tolist(),
        "cost": r.cost,
        "targets": [
            {"index": i, "closest_t": None if np.isinf(t) else float(t), "distance": float(d)}
            for i, (t, d) in enumerate(zip(r.closest_t, r.distances, strict=True))
        ],
        "cost_history": [float(x) for x in r.cost_history],
        "stage_history": list(r.stage_history),
        "winning_start": r.winning_start,
        "starts_tried": r.starts_tried,
        "status": r.status,
        "loops": list(r.loops),
        "loop_fixed": r.loop_fixed,
    }
