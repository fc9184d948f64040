"""One start of the motion evolution (paper Sec. 4.3, MATH section 8); see :mod:`.evolution`.

Per start (:func:`evolve_start`, all in the S_0 frame): stages initial (weight w0, guides by
proportional spacing (2b), 7-parameter factors + axis projection) -> middle (closest-pose guides
(2a), weight reduced by q per iteration down to 1) -> final (6-parameter factors, w = 1, optional
free frame X). Stage changes follow the cyclic order of the closest poses; a broken order sends
the start back to the initial stage. Every iteration is one Gauss-Newton step (central-difference
Jacobian in one batched call, minimum-norm least squares) with a batched backtracking line search
on the frozen-guide objective.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from paraloop_core.algebra import dq, poly
from paraloop_core.motion import closest, metric

_STEPS = 0.5 ** np.arange(20)  # backtracking step sizes, all tried in one batched call
_CASE_PAIRS = np.array([[0, 1], [0, 2], [1, 2]])  # final-stage dual bases per case (MATH 8)
_EXACT = 1e-16  # cost / scale at which a fit counts as exact (round-off level of the closest t)
_INITIAL_CAP = 30  # consecutive initial-stage iterations before a start counts as unordered


@dataclass(frozen=True)
class EvolutionSettings:
    """Options of the evolution (MATH section 8, section 14 item 8).

    ``w0`` initial orientation weight (> 1 favours orientation), ``q`` weight reduction per
    middle-stage iteration (fraction), ``tol`` relative cost improvement below which a stage ends,
    ``max_iterations`` cap per start (doubled with the loop fix), ``starts`` number of starts,
    ``seed`` of the random starts, ``workers`` processes, ``init`` 'random' (eq. 9) or
    'four-pose' (start 0 interpolates ``four_pose_indices``, default spread over the targets),
    ``free_reference`` frame X in the final stage, ``ordered`` targets, ``loop_fix`` modified
    procedure against the loop phenomenon (Fig. 17), ``loop_ratio`` arc/chord ratio flagging a
    loop between adjacent targets, ``virtual`` virtual targets per gap in the loop fix,
    ``move_guides``: with closest-pose guides the Gauss-Newton step also moves the guiding
    parameters (joint step in (x, t): fast convergence); False freezes them (MATH 8 literally,
    linear convergence); ``smooth_drive`` weight >= 0 of the smooth-drive penalty in the
    ranking of finished starts (0: by cost alone; :func:`.evolution.best_start`).
    """

    w0: float = 3.0
    q: float = 0.10
    tol: float = 1e-4
    max_iterations: int = 100
    starts: int = 20
    seed: int = 0
    workers: int = 1
    init: str = "random"
    four_pose_indices: tuple[int, int, int, int] | None = None
    free_reference: bool = False
    ordered: bool = True
    loop_fix: bool = False
    loop_ratio: float = 3.0
    virtual: int = 1
    move_guides: bool = True
    smooth_drive: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.w0) and self.w0 >= 1.0):
            raise ValueError(f"w0 must be a number >= 1, got {self.w0!r}")
        if not 0.0 < self.q < 1.0:
            raise ValueError(f"q must lie in (0, 1), got {self.q!r}")
        if not (np.isfinite(self.tol) and self.tol > 0):
            raise ValueError(f"tol must be positive, got {self.tol!r}")
        for name in ("max_iterations", "starts", "workers"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)!r}")
        if self.init not in ("random", "four-pose"):
            raise ValueError(f"init must be 'random' or 'four-pose', got {self.init!r}")
        if self.four_pose_indices is not None and (
            len(self.four_pose_indices) != 4 or self.four_pose_indices[0] != 0
            or len(set(self.four_pose_indices)) != 4 or min(self.four_pose_indices) < 0
        ):
            raise ValueError("four_pose_indices must be 4 distinct target indices starting with 0")
        if not self.loop_ratio > 1.0 or self.virtual < 1:
            raise ValueError("loop_ratio must be > 1 and virtual >= 1")
        if not (np.isfinite(self.smooth_drive) and self.smooth_drive >= 0):
            raise ValueError(f"smooth_drive must be a number >= 0, got {self.smooth_drive!r}")


@dataclass(frozen=True)
class Problem:
    """Targets prepared for one evolution (S_0 frame, unit poses).

    ``targets`` ``(m, 8)`` the real targets (``targets[0] = 1``); ``guides`` ``(g, 8)`` the poses
    the guiding poses are fitted to (the targets, plus virtual ones with the loop fix);
    ``real`` ``(m,)`` index of each target in ``guides``; ``inertia`` the user's metric (its
    weight is the base that the stage weight w multiplies: w = 1 is the original metric);
    ``scale`` the summed squared target chords (cost scale).
    """

    targets: np.ndarray
    guides: np.ndarray
    real: np.ndarray
    inertia: metric.Inertia
    scale: float


@dataclass(frozen=True)
class StartResult:
    """Outcome of one start: ``status`` ('converged', 'stalled' = cap reached while ordered,
    'unordered' = never (stably) ordered, 'degenerate'); ``factors`` ``(3, 8)`` and ``frame`` X
    ``(8,)`` (S_0 frame); ``cost_history`` true cost (w = 1, closest poses) per iteration
    (index 0: initial guess); ``stage_history`` stage of each step; ``steps`` frozen-guide
    objective (before, after) of each step; ``loops`` gaps i (target i -> i+1) with a loop;
    ``loop_fixed`` whether the modified procedure (virtual targets, Fig. 17) produced it."""

    index: int
    status: str
    factors: np.ndarray
    frame: np.ndarray
    cost_history: tuple[float, ...]
    stage_history: tuple[str, ...]
    steps: tuple[tuple[float, float], ...]
    loops: tuple[int, ...]
    loop_fixed: bool = False


# ---------------------------------------------------------------- parametrizations
def h_from_x7(x: np.ndarray) -> np.ndarray:
    """Factors ``(..., 3, 8)`` from 7-parameter rows ``(..., 3, 7)`` = (x0, p, d), dual scalar 0."""
    z = np.zeros(x.shape[:-1] + (1,))
    return np.concatenate([x[..., :4], z, x[..., 4:]], axis=-1)


def project_axes(x: np.ndarray) -> np.ndarray:
    """Eq. 5 on the axes of 7-parameter rows ``(..., 7)``: ``d <- d - (p.d / |p|^2) p``."""
    p, d = x[..., 1:4], x[..., 4:7]
    pp = np.maximum(np.sum(p * p, -1, keepdims=True), 1e-300)
    return np.concatenate([x[..., :4], d - np.sum(p * d, -1, keepdims=True) / pp * p], axis=-1)


def final_basis(p: np.ndarray, case: np.ndarray) -> np.ndarray:
    """Dual-part bases ``(..., 2, 3)`` of the final stage for axis directions ``p`` ``(..., 3)``:
    cases 0/1/2 (largest |x1|/|x2|/|x3|) use two of (x2,-x1,0), (x3,0,-x1), (0,x3,-x2)."""
    x1, x2, x3 = np.moveaxis(p, -1, 0)
    z = np.zeros_like(x1)
    vecs = np.stack(
        [np.stack([x2, -x1, z], -1), np.stack([x3, z, -x1], -1), np.stack([z, x3, -x2], -1)], -2
    )
    idx = np.broadcast_to(_CASE_PAIRS[case], vecs.shape[:-2] + (2,))
    return np.take_along_axis(vecs, idx[..., None], axis=-2)


def h_from_x6(x: np.ndarray, case: np.ndarray) -> np.ndarray:
    """Factors ``(..., 3, 8)`` from 6-parameter rows ``(..., 3, 6)`` = (x0, p, x5, x6)."""
    d = np.einsum("...k,...kj->...j", x[..., 4:6], final_basis(x[..., 1:4], case))
    return h_from_x7(np.concatenate([x[..., :4], d], axis=-1))


def x6_from_h(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Convert projected factors ``(3, 8)`` to ``(x6 (3, 6), case (3,))`` (case re-chosen; exact
    least squares since d is orthogonal to p)."""
    case = np.argmax(np.abs(h[:, 1:4]), axis=-1)
    b = final_basis(h[:, 1:4], case)  # (3, 2, 3)
    coef = np.linalg.solve(b @ np.swapaxes(b, -1, -2), b @ h[:, 5:8, None])[..., 0]
    return np.concatenate([h[:, :4], coef], axis=-1), case


def motion(h: np.ndarray, frame: np.ndarray | None = None) -> np.ndarray:
    """Cubic ``X (t - h_1)(t - h_2)(t - h_3)`` ``(..., 4, 8)`` from factors ``(..., 3, 8)``."""
    c = poly.from_factors(h)
    return c if frame is None else dq.mul(frame[..., None, :], c)


# ---------------------------------------------------------------- one Gauss-Newton step
def _residuals(h, frame, t, target_pts, verts):
    """Residuals ``(B, k*18)`` of factor batches ``(B, 3, 8)`` at frozen guides ``t`` ``(k,)``;
    ``|r|^2 = sum_i dist^2(C(t_i), S_i)`` (MATH 8)."""
    poses = poly.evaluate_pose(motion(h, frame)[:, None], t)  # (B, k, 8)
    pts = dq.transform_points(poses[:, :, None, :], verts)  # (B, k, 6, 3)
    return ((pts - target_pts) / np.sqrt(6.0)).reshape(len(h), -1)


def gauss_newton_step(x, residual_fn, post, bound=None):
    """One damped Gauss-Newton step on parameters ``x`` ``(n,)``.

    ``residual_fn`` maps ``(B, n) -> (B, R)``; ``post`` maps candidates ``(B, n)`` back onto
    the feasible set (projection). Jacobian of ``r o post`` by central differences (all ``2n``
    perturbations in one call), minimum-norm step, ``|dx| <= bound (1 + |x|)`` when bounded,
    backtracking over step sizes 1, 1/2, ... (one call). Returns ``(x_new, f_before,
    f_after)``; ``x`` unchanged when no step size lowers the objective.
    """
    n = x.size
    r0 = residual_fn(x[None])[0]
    f0 = float(r0 @ r0)
    e = 1e-6 * (1.0 + np.abs(x))
    # Jacobian of r o post: directions the projection removes get zero columns, so the step
    # stays (to first order) on the feasible set and remains a descent direction after it.
    rp = residual_fn(post(x + np.concatenate([np.diag(e), -np.diag(e)])))
    jac = ((rp[:n] - rp[n:]) / (2.0 * e[:, None])).T
    # Truncate singular values at the central-difference noise level: the parametrization
    # is redundant (e.g. t -> a t + b with the guide parameters), so exact null directions
    # show up as tiny nonzero singular values.
    dx = np.linalg.lstsq(jac, -r0, rcond=1e-7)[0]
    if bound is not None:
        dx *= min(1.0, bound * (1.0 + np.linalg.norm(x)) / max(np.linalg.norm(dx), 1e-300))
    cand = post(x + _STEPS[:, None] * dx)
    f = np.sum(residual_fn(cand) ** 2, axis=-1)
    ok = np.isfinite(f) & (f < f0)
    if not np.any(ok):
        return x, f0, f0
    k = int(np.argmax(ok))
    return cand[k], f0, float(f[k])


def cyclic_order(t: np.ndarray) -> np.ndarray:
    """+1 / -1 where the parameters ``t`` ``(..., m)`` (``t[..., 0]`` the pose of S_0) are
    visited in order going forward / backward round the cycle exactly once, else 0 (``(...)``)."""
    u = poly.t_to_param(t)
    gaps = np.diff(np.concatenate([u, u[..., :1]], axis=-1), axis=-1)
    out = np.zeros(u.shape[:-1], dtype=int)
    for sign in (-1, 1):
        g = np.mod(sign * gaps, 1.0)
        ok = np.all(g > 1e-9, axis=-1) & (np.abs(np.sum(g, -1) - 1.0) < 1e-6)
        out = np.where(ok, sign, out)
    return out


def loop_gaps(c, t, direction, targets, inertia, ratio, samples: int = 1024) -> tuple[int, ...]:
    """Gaps i (target i -> i+1, closing gap excluded) whose arc along the cycle of ``c``
    (``direction`` +-1) exceeds ``ratio`` times the chord: the loop phenomenon (Fig. 17).

    Each gap's arc is the chord sum over ``samples`` parameters spread over that gap alone: a
    loop the motion runs through quickly (a short ``u`` interval, much shorter than a cell of
    a whole-cycle table) is still resolved. Chord sums only underestimate the arc.
    """
    u = poly.t_to_param(np.asarray(t, dtype=np.float64))
    span = np.mod(direction * np.diff(u), 1.0)  # (m-1,)
    uu = np.mod(u[:-1, None] + direction * span[:, None] * np.linspace(0.0, 1.0, samples), 1.0)
    poses = poly.evaluate_pose(c, poly.param_to_t(uu))  # (m-1, samples, 8)
    arcs = np.sum(np.sqrt(np.maximum(metric.distance_sq(poses[:, :-1], poses[:, 1:], inertia),
                                     0.0)), axis=-1)
    chords = np.sqrt(metric.distance_sq(targets[:-1], targets[1:], inertia))
    return tuple(int(i) for i in np.flatnonzero(arcs > ratio * chords))


# ---------------------------------------------------------------- one start
def next_stage(stage: str, in_order: bool, w: float, gain: float,
               settings: EvolutionSettings) -> str:
    """Stage after an iteration (Sec. 4.3): initial -> middle once the closest poses are in
    order; middle -> final once w = 1 and the relative gain < tol; final -> 'converged' once
    the gain < tol; an order break in middle/final returns to initial (ordered targets only)."""
    if settings.ordered and stage == "initial":
        return "middle" if in_order else "initial"
    if settings.ordered and not in_order:
        return "initial"
    if stage == "middle" and w == 1.0 and gain < settings.tol:
        return "final"
    if stage == "final" and gain < settings.tol:
        return "converged"
    return stage


def _stage_step(prob, stage, w, h, frame, t_guides, free, bound, move):
    """One step of ``stage``: returns ``(h, frame, f_before, f_after)``. ``move``: the step also
    moves the guiding parameters (joint Gauss-Newton in (x, u)); else they stay frozen."""
    inertia = prob.inertia.with_weight(prob.inertia.weight * w)
    verts = inertia.vertices
    use = np.arange(len(prob.guides)) if free else np.arange(1, len(prob.guides))
    target_pts = dq.transform_points(prob.guides[use, None, :], verts)
    tg = t_guides[use]
    if stage != "final":
        def unpack(xb):
            return h_from_x7(xb.reshape(-1, 3, 7)), None

        def post(xb):
            return project_axes(xb.reshape(-1, 3, 7)).reshape(len(xb), -1)

        x = h[:, [0, 1, 2, 3, 5, 6, 7]].ravel()
    else:
        x6, case = x6_from_h(h)

        def unpack(xb):
            return h_from_x6(xb[:, :18].reshape(-1, 3, 6), case), xb[:, 18:] if free else None

        def post(xb):
            if not free:
                return xb
            return np.concatenate([xb[:, :18], dq.study_project(dq.normalize(xb[:, 18:]))], 1)

        x = np.r_[x6.ravel(), frame] if free else x6.ravel()

    k = len(tg)

    def residual_fn(xb):
        nx = xb.shape[1] - (k if move else 0)
        hb, fb = unpack(xb[:, :nx])
        return _residuals(hb, fb, poly.param_to_t(xb[:, nx:]) if move else tg, target_pts, verts)

    def post_all(xb):
        return np.concatenate([post(xb[:, : x.size]), xb[:, x.size :]], axis=1)

    z = np.r_[x, poly.t_to_param(tg)] if move else x
    z_new, f0, f1 = gauss_newton_step(z, residual_fn, post_all, bound)
    h_new, f_new = unpack(z_new[None, : x.size])
    return h_new[0], (frame if f_new is None else f_new[0]), f0, f1


def evolve_start(prob: Problem, settings: EvolutionSettings, h0: np.ndarray, index: int = 0,
                 loop_fix: bool = False) -> StartResult:
    """Run the three-stage evolution from initial factors ``h0`` ``(3, 8)`` (S_0 frame)."""
    ordered = settings.ordered
    stage = "initial" if ordered else "middle"
    w = settings.w0
    h = h_from_x7(project_axes(h0[:, [0, 1, 2, 3, 5, 6, 7]]))
    frame = dq.IDENTITY.copy()
    costs, stages, steps = [], [], []
    cap = settings.max_iterations * (2 if loop_fix else 1)
    bound = 0.1 if loop_fix else None
    status, direction, in_initial = "stalled", 1, 0
    for it in range(cap + 1):
        if not (np.all(np.isfinite(h)) and np.all(np.isfinite(frame))):
            status = "degenerate"
            break
        c = motion(h, frame)
        t_all, d2 = closest.closest_pose(c, prob.targets, prob.inertia, robust=False)
        free = settings.free_reference and stage == "final"
        if not free:
            t_all[0], d2[0] = np.inf, 0.0
        cost = float(np.sum(d2))
        if not np.isfinite(cost):
            status = "degenerate"
            break
        costs.append(cost)
        # relative improvement of the last step's own objective (guides frozen at that step)
        gain = (steps[-1][0] - steps[-1][1]) / steps[-1][0] if steps and steps[-1][0] else 1.0
        if cost <= _EXACT * prob.scale:
            gain = 0.0
        direction = int(cyclic_order(t_all)) if ordered else 1
        new = next_stage(stage, bool(direction), w, gain, settings)
        if new == "converged":
            status = "converged"
            break
        if new == "initial" and stage != "initial":  # order broke: back to the start values
            w, frame = settings.w0, dq.IDENTITY.copy()
        stage = new
        in_initial = in_initial + 1 if stage == "initial" else 0
        if it == cap or in_initial > _INITIAL_CAP:
            break
        free = settings.free_reference and stage == "final"
        weight = 1.0 if stage == "final" else w
        inertia_w = prob.inertia.with_weight(prob.inertia.weight * weight)
        t_w, _ = closest.closest_pose(motion(h, frame), prob.guides, inertia_w, robust=False)
        proportional = stage == "initial" or loop_fix
        if proportional:
            t_g = np.r_[t_w[0] if free else np.inf,
                        closest.proportional_params(motion(h, frame), prob.guides, inertia_w,
                                                    t_w[1])]
        else:
            t_g = t_w
        move = settings.move_guides and not proportional
        try:
            h, frame, f0, f1 = _stage_step(prob, stage, weight, h, frame, t_g, free, bound, move)
        except np.linalg.LinAlgError:  # e.g. a factor became a translation (final basis = 0)
            status = "degenerate"
            break
        stages.append(stage)
        steps.append((f0, f1))
        if stage == "middle":
            w = max(1.0, w * (1.0 - settings.q))
    if status == "stalled" and ordered and (stage == "initial" or not direction):
        status = "unordered"
    loops: tuple[int, ...] = ()
    if ordered and status in ("converged", "stalled"):
        loops = loop_gaps(motion(h, frame), t_all, direction, prob.targets, prob.inertia,
                          settings.loop_ratio)
    return StartResult(index, status, h, frame, tuple(costs), tuple(stages), tuple(steps), loops,
                       loop_fix)
