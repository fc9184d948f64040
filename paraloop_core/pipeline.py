"""Design -> solution: motion, six factorizations, nine loops, singularity, realization (or,
from three poses, the Bennett quadratic, its two factorizations and its 4R loop, not realized).

The result JSON (``docs/result-format.md``) is produced by :func:`result_to_dict`.
World frame throughout: the motion is ``C(t) = M(t) S_0`` with ``M`` monic, so ``C(inf) ∝ S_0``
and the factors of ``M`` are rotation axes in world coordinates.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from paraloop_core.algebra import dq, factor
from paraloop_core.design import Design, check_pose_count, mesh_file
from paraloop_core.design_checks import design_field
from paraloop_core.errors import ParaloopError, RealizationError
from paraloop_core.linkage import bennett, loops, singularity
from paraloop_core.motion import fourpose, metric, threepose
from paraloop_core.result import result_to_dict

#: Work units (:meth:`realize.Search.work`, about 0.3 ms each on one core) of the realization
#: attempts: the design's own loop and parameters first, then each fallback. A budget, not a
#: clock: the answer is the same on every machine, under any load and at every scale.
FIRST_ATTEMPT_WORK = 40_000
FALLBACK_WORK = 12_000


@dataclass(frozen=True)
class Solution:
    """Everything computed from a design (arrays in world coordinates, design units)."""

    design: Design
    motion: np.ndarray  # (n+1, 8) C(t) = M(t) S_0, ascending powers; n = 3, Bennett n = 2
    monic: np.ndarray  # (n+1, 8) M(t), monic
    reference: np.ndarray  # (8,) S_0 (unit)
    pose_parameters: np.ndarray  # (m,) t_i with C(t_i) ∝ S_i; inf for S_0
    mu: float | None  # family parameter used (None = inf)
    factorizations: factor.Factorizations  # six (Bennett: two)
    loops: list[loops.Loop]  # the nine 6R loops (Bennett: its one 4R loop)
    singularity: np.ndarray  # (9,) / (1,) min over the cycle of the singularity measure
    singularity_t: np.ndarray  # (9,) / (1,) where the min occurs (inf allowed)
    realization: Any = None  # certified.Realization or None
    fit: Any = None  # evolution.FitResult for method 'fit', else None
    end_effector: Any = None  # ee_certificate.EndEffectorRealization when the design has one
    #: JSON-ready: ``status`` found | not_found, ``attempts``, ``reason``/``fallback``
    realization_report: dict | None = None
    unit: float = 1.0  # :func:`unit_length` of the targets, design units
    #: ``(9, 6, 8)`` (Bennett ``(1, 4, 8)``) the loops' joint factors in ``unit`` (the
    #: numbers the realization searches: the same bits in any unit of the design); None =
    #: ``loops`` in ``unit`` 1
    loop_factors_unit: np.ndarray | None = None

    def search_factors(self, loop: int) -> tuple[np.ndarray, float]:
        """Joint factors ``(6, 8)`` of ``loop`` for the realization and their unit."""
        if self.loop_factors_unit is None:
            return self.loops[loop].joint_factors, 1.0
        return self.loop_factors_unit[loop], self.unit

    @property
    def loop(self) -> loops.Loop:
        return self.loops[self.design.loop]

    def other_loops(self) -> dict[int, np.ndarray]:
        """Joint factors ``(6, 8)`` of the loops other than the design's, by loop index (the
        alternatives an export may realize when the design's loop is too thin to print)."""
        return {i: lp.joint_factors for i, lp in enumerate(self.loops) if i != self.design.loop}


def design_poses(design: Design) -> np.ndarray:
    """Unit world poses ``(m, 8)`` of the design's targets."""
    pos, wxyz = design.pose_array
    return dq.from_pos_wxyz(pos, wxyz)


def inertia_of(design: Design, unit: float = 1.0) -> metric.Inertia:
    """The design's inertia ellipsoid, lengths in ``unit`` design units."""
    s = design.inertia
    return metric.Inertia(s.center / unit, s.axes, s.semi_axes / unit, s.weight)


#: Grid of target positions in :func:`unit_length` (2^-40, 1e-12 of the design's size):
#: positions that differ in the last bits, as a design and its copy in other units do, land
#: on the same grid point unless they straddle a midpoint (about 1 design in 500; it then
#: changes only an ill-conditioned motion's answer).
UNIT_GRID = 2.0**-40


def on_unit_grid(x: np.ndarray) -> np.ndarray:
    """``x`` (lengths in :func:`unit_length`, of order 1) rounded to :data:`UNIT_GRID`."""
    return np.round(np.asarray(x, dtype=np.float64) / UNIT_GRID) * UNIT_GRID


def unit_length(poses: np.ndarray) -> float:
    """Characteristic length of unit poses ``(m, 8)``: the root mean square distance of the
    targets from the origin (1 when all sit at it). Motion design runs in this unit, so a
    uniform change of the design's unit changes no digit of the answer beyond rounding."""
    rms = float(np.sqrt(np.mean(np.sum(dq.translation_of(poses) ** 2, axis=-1))))
    return rms if np.isfinite(rms) and rms > 0 else 1.0


def _four_pose(design: Design, poses: np.ndarray, unit: float
               ) -> tuple[np.ndarray, np.ndarray, float | None]:
    """Relative monic cubic (S_0 frame) of ``poses`` given in ``unit`` design units, the
    visiting parameters and the mu used."""
    fams = fourpose.four_pose_families(poses)
    m = design.motion
    mu = m.mu
    if m.criterion is not None:
        from paraloop_core.motion import selection  # only needed when a criterion picks mu

        mu, _ = selection.best_mu(fams, m.family, m.criterion,
                                  **_criterion_params(design, unit))
    c_rel = fourpose.four_pose_motion(fams, m.family, mu)
    return c_rel, np.concatenate([[np.inf], fams.t[m.family]]), mu


def _criterion_params(design: Design, unit: float) -> dict[str, Any]:
    """Parameters of the design's selection criterion (validated by the design loader), lengths
    in ``unit`` design units."""
    m = design.motion
    if m.criterion == "length":
        return {"inertia": inertia_of(design, unit)}
    if m.criterion in ("base-axes", "end-axes"):
        return {"loop": design.loop, "points": None if m.targets is None else m.targets / unit}
    if m.criterion == "smooth-drive":  # the design's motor, else the best one
        return {"loop": design.loop, "motor": design.drive.motor}
    extra = np.array([dq.from_pos_wxyz(p.position / unit, p.wxyz) for p in m.extra_poses])
    return {"poses": extra, "inertia": inertia_of(design, unit)}


def solve(design: Design, *, realize: bool = True, other_loops: bool = True,
          progress: Callable[[float, str], None] | None = None,
          hint: Solution | None = None, fit: Any = None,
          pattern: tuple[np.ndarray, np.ndarray] | None = None,
          quick_work: int | None = None, check: Callable[[], None] | None = None) -> Solution:
    """Compute the solution of a design; raises ParaloopError subclasses (ValueError) with a
    clear message for degenerate poses, non-generic motions or impossible realization
    parameters. A Bennett design (method 'three-pose') gets the quadratic through its poses,
    both factorizations and the 4R loop; its realization is reported ``not_found`` with
    :data:`BENNETT_REALIZATION` (not searched), and ``hint``, ``pattern``, ``quick_work`` do
    not apply. A realization that is not found is not an error: the solution then carries
    ``realization_report['status'] == 'not_found'`` with the reason and the attempts (the
    design's loop, thinner bars, then with ``other_loops`` the other loops, each with its
    work budget: :data:`FIRST_ATTEMPT_WORK`, :data:`FALLBACK_WORK`). ``progress(fraction,
    message)`` is called during a fit (it may raise to stop the fit). ``hint``: a solution of
    a nearby design (the previous drag step) whose realization is tried first on the same
    loop (:func:`realize.warm_start`, certified as any other answer) and whose fit starts the
    first evolution start. ``fit``: an :class:`evolution.FitResult` already computed for this
    design's targets (the studio's drag preview), used instead of running the evolution.
    ``pattern``: shifts and offsets (a drag preview's, :class:`WarmPreview`) tried first, like
    ``hint``'s and certified as any answer. ``quick_work``: search only the design's own loop
    and parameters, within this many work units; a miss is reported ``not_found`` with
    ``incomplete: True`` (the studio's release; the full search follows in the background).
    ``check()`` is called between search candidates and may raise to stop.

    The motion (four-pose; a fit's is converted), its factorizations, loops and singularity
    are computed in :func:`unit_length` from the targets put on the :func:`on_unit_grid`, and
    the realization searches these loops: a change of the design's unit then gives bit-identical
    decisions (same loop, shifts, offsets, relative clearances) even for ill-conditioned
    motions, whose answer a last-bit difference of the input can change."""
    check_pose_count(design)
    if quick_work is not None and not (isinstance(quick_work, int) and quick_work >= 1):
        raise ValueError(f"quick_work must be a positive integer or None, got {quick_work!r}")
    poses = design_poses(design)
    unit = unit_length(poses)
    if design.motion.method == "fit":
        from paraloop_core.motion import evolution  # only needed for fitted motions

        warm = None if hint is None or hint.fit is None else hint.fit.factors
        fit = fit or evolution.fit_motion(poses, inertia_of(design),
                                          evolution.evolution_settings(design.evolution),
                                          progress, warm)
        c_rel, pose_t, mu = dq.scale_lengths(fit.motion_rel, 1.0 / unit), fit.closest_t, None
        reference, reference_u = fit.reference, dq.scale_lengths(fit.reference, 1.0 / unit)
    else:
        fit = None
        pos, wxyz = design.pose_array
        poses_u = dq.from_pos_wxyz(on_unit_grid(pos / unit), wxyz)
        if design.linkage == "bennett":
            c_rel, mu = threepose.three_pose_motion(poses_u), None
            pose_t = np.concatenate([[np.inf], threepose.POSE_PARAMETERS])
        else:
            c_rel, pose_t, mu = _four_pose(design, poses_u, unit)
        reference_u = poses_u[0]
        reference = dq.scale_lengths(reference_u, unit)  # S_0 on the grid (1e-12 of the size)
    monic_u = fourpose.world_motion(reference_u, c_rel)
    if design.linkage == "bennett":
        facts_u = factor.quadratic_factorizations(monic_u)
        jf_u = bennett.loop_joint_factors(facts_u.factors)[None]  # (1, 4, 8)
        s_min, s_t = bennett.singularity_min(jf_u, length=1.0)
        make_loops = bennett.bennett_loops
    else:
        facts_u = factor.all_factorizations(monic_u)
        jf_u = loops.loop_joint_factors(facts_u.factors)  # (9, 6, 8), as nine_loops orders them
        s_min, s_t = singularity.singularity_min(jf_u, length=1.0)
        make_loops = loops.nine_loops
    monic = dq.scale_lengths(monic_u, unit)
    facts = replace(facts_u, factors=dq.scale_lengths(facts_u.factors, unit))
    motion = dq.mul(monic, reference)
    sol = Solution(design, motion, monic, reference, pose_t, mu, facts, make_loops(facts),
                   s_min, s_t, fit=fit, unit=unit, loop_factors_unit=jf_u)
    if realize and design.realization.enabled and design.linkage == "bennett":
        return replace(sol, realization_report={
            "status": "not_found", "attempts": [], "reason": BENNETT_REALIZATION,
            "advice": "use the loop's axes in 'loops' (a realization needs the search and the "
                      "certificate generalized to four joints)"})
    if realize and design.realization.enabled:
        try:
            warm = warm_realization(sol, hint, pattern)
            sol = warm if warm is not None else _with_realization(sol, other_loops, quick_work,
                                                                  check)
        except ParaloopError as exc:  # the user's own settings: name the field
            field = design_field(exc.param, design)
            if field is not None and not hasattr(exc, "field"):
                exc.in_field(field)
            raise
    return sol


def _params(sol: Solution, rho_f: float = 1.0, d_f: float = 1.0) -> dict[str, Any]:
    """Realization keyword arguments of the design, bars ``rho_f`` thinner, ``d_f`` closer."""
    r = sol.design.realization
    return dict(p=r.p, rho=None if r.rho is None else r.rho * rho_f,
                d=None if r.d is None else r.d * d_f, d_fraction=r.d_fraction * d_f,
                rho_fraction=r.rho_fraction * rho_f / d_f, fixed=dict(r.fixed), max_k=r.max_k)


#: Work units (:meth:`realize.Search.work`) of the search a drag preview runs when the last
#: realization's pattern does not clear the new loop: thin checks and exact minima only, no
#: sound bounds (the release certifies the pattern it finds).
PREVIEW_WORK = 1500


@dataclass(frozen=True)
class WarmPreview:
    """A drag preview (:func:`warm_preview`): vertices ``points`` ``(12, 3)`` (design units,
    home), with an end-effector the attached ``effector``, and the ``pattern`` ``(shifts,
    offsets)`` that gave them (the release tries it first). Never a certificate."""

    points: np.ndarray
    effector: Any = None
    pattern: tuple[np.ndarray, np.ndarray] | None = None

    def end_link(self) -> np.ndarray:
        """End-link path ``(4, 3)`` at home, ``S_3, L, R, E_3`` (with an end-effector)."""
        v, e = self.points, self.effector
        return np.stack([v[6], e.vertices[e.L], e.vertices[e.R], v[7]])


def _hint_pattern(sol: Solution, hint: Solution | None) -> tuple[np.ndarray, np.ndarray] | None:
    """``(shifts, offsets)`` of ``hint``'s realization when it realized ``sol``'s loop with the
    same end-effector kind, else None."""
    real = None if hint is None else hint.realization
    if (real is None or hint.design.loop != sol.design.loop
            or not sol.design.realization.enabled
            or (hint.end_effector is None) != (sol.design.end_effector is None)):
        return None
    return real.shifts, real.offsets


def _pattern_search(sol: Solution, pattern: tuple | None = None
                    ) -> tuple[Any, Any, dict[str, Any]]:
    """``(search, effector, keyword arguments)`` on ``sol``'s loop: those of ``run_hint`` for
    ``pattern`` ``(shifts, offsets)``, else of ``run``."""
    from paraloop_core.realization import realize as realize_mod

    params = _params(sol)
    fixed = params.pop("fixed")
    if pattern is not None:
        params.update(shifts=pattern[0], offsets=pattern[1])
    jf, in_unit = sol.search_factors(sol.design.loop)
    if sol.design.end_effector is None:
        return realize_mod.Search(jf, fixed, in_unit), None, params
    from paraloop_core.realization import realize_ee

    effector = attach_end_effector(sol)
    search = realize_ee.EffectorSearch(jf, fixed, effector, sol.design.end_effector.clearance,
                                       in_unit)
    return search, effector, params


def warm_preview(sol: Solution, hint: Solution) -> WarmPreview | None:
    """``sol``'s loop with the shifts and offsets of ``hint``'s realization when the thin
    checks (P included) and the exact minima (Sec. 5.1) clear them; else (no end-effector)
    the first pattern a search of :data:`PREVIEW_WORK` units finds with the same checks; else
    None. Not certified (no sound bounds): a drag shows it, the release certifies
    (:func:`warm_realization`)."""
    pattern = _hint_pattern(sol, hint)
    try:
        if pattern is not None:
            search, effector, params = _pattern_search(sol, pattern)
            pts = search.run_hint(**params, certify=False)
            if pts is not None:
                return WarmPreview(pts, effector, pattern)
        if sol.design.end_effector is not None or not sol.design.realization.enabled:
            return None
        search, _, params = _pattern_search(sol)
        shifts, offsets, pts = search.run(**params, budget=PREVIEW_WORK, certify=False)
    except (RealizationError, ValueError):  # e.g. a mesh gone: the full update says why
        return None
    return WarmPreview(pts, None, (shifts, offsets))


def warm_realization(sol: Solution, hint: Solution | None,
                     pattern: tuple[np.ndarray, np.ndarray] | None = None) -> Solution | None:
    """``sol`` realized with ``pattern`` ``(shifts, offsets)`` (a drag preview's) or else the
    shifts and offsets of ``hint``'s realization (same loop and end-effector kind), when they
    realize ``sol``'s loop, certified as any answer; else None. Cheap (one candidate each)."""
    tried = []
    for pat in (pattern, _hint_pattern(sol, hint)):
        if pat is None or any(np.array_equal(pat[0], a) and np.array_equal(pat[1], b)
                              for a, b in tried):
            continue
        tried.append(pat)
        try:
            search, effector, params = _pattern_search(sol, pat)
            out = search.run_hint(**params)
        except (RealizationError, ValueError):  # a spherical loop, a mesh gone: the search
            continue  # says why
        if out is not None:
            real, ee = (out, None) if effector is None else (out.realization, out)
            report = {"status": "found", "attempts": [], "fallback": None, "warm_start": True}
            return replace(sol, realization=real, end_effector=ee, realization_report=report)
    return None


#: Why a Bennett design is reported ``not_found`` (docs/result-format.md): never searched.
BENNETT_REALIZATION = (
    "Bennett realization not yet supported: the collision-free search and its certificate "
    "(realization.realize) are written for the six joints of a 6R loop (12 vertices, 42 bar "
    "pairs); the Bennett 4R loop's axes are in 'loops'")


#: Largest singularity measure (unit-free, the best of the nine loops) below which a design
#: that is not realized is reported as nearly degenerate (random design 12: 1e-20).
NEAR_SINGULAR = 1e-12

#: Fallback attempts on the chosen loop: factors of (rho, d) after the design's own values.
_SHRINK = ((0.5, 1.0), (0.25, 0.5))
#: Last pass, every loop: thin bars at the design's offsets. Nearly singular motions (S < 1e-7)
#: pass close to themselves; there thin bars at full offsets clear where the two above do not
#: (9 of the 12 designs of random seeds 20000..20999 not realized otherwise).
_THIN = (0.2, 1.0)


def _attempts(sol: Solution, other_loops: bool) -> list[tuple[int, float, float]]:
    """``(loop, rho factor, d factor)`` in the order tried: the design's loop and parameters,
    thinner bars / closer offsets, the other loops farthest from a singular motion, then
    :data:`_THIN` bars on each loop in the same order."""
    mine = sol.design.loop
    order = [mine] + ([int(k) for k in np.argsort(-sol.singularity, kind="stable") if k != mine]
                      if other_loops else [])
    return ([(mine, 1.0, 1.0)] + [(mine, r, d) for r, d in _SHRINK]
            + [(k, 1.0, 1.0) for k in order[1:]] + [(k, *_THIN) for k in order])


def _with_realization(sol: Solution, other_loops: bool, quick_work: int | None = None,
                      check: Callable[[], None] | None = None) -> Solution:
    """The first realization of :func:`_attempts` (``status: found``; the solution's loop is
    the realized one), or the solution with a ``not_found`` report (reason, attempts); with
    ``quick_work`` only the first attempt, within that budget (see :func:`solve`)."""
    from paraloop_core.realization import realize as realize_mod

    tried: list[dict[str, Any]] = []
    attempts = _attempts(sol, other_loops)[:1 if quick_work is not None else None]
    for n, (loop, rho_f, d_f) in enumerate(attempts):
        attempt = replace(sol, design=replace(sol.design, loop=loop))
        jf, in_unit = sol.search_factors(loop)
        budget = quick_work if quick_work is not None else (
            FALLBACK_WORK if n else FIRST_ATTEMPT_WORK)
        params = dict(_params(sol, rho_f, d_f), in_unit=in_unit, budget=budget, check=check)
        try:
            if sol.design.end_effector is None:
                real = realize_mod.realize(jf, **params)
                ee = None
            else:
                from paraloop_core.realization import realize_ee

                ee = realize_ee.realize_with_effector(
                    jf, attach_end_effector(attempt), **params,
                    ee_clearance=sol.design.end_effector.clearance)
                real = ee.realization
        except RealizationError as exc:
            if exc.reason == "bad-parameters" and not tried:
                raise  # the user's own parameters are impossible: say so, do not guess
            tried.append({"loop": loop, "rho_factor": rho_f, "d_factor": d_f,
                          "reason": exc.reason, "message": str(exc)})
            continue
        report = {"status": "found", "attempts": tried,
                  "fallback": None if not tried else (
                      f"the design's loop {sol.design.loop} with rho x1, d x1 was not "
                      f"realized; realized loop {loop} with rho x{rho_f:g}, d x{d_f:g}")}
        return replace(attempt, realization=real, end_effector=ee, realization_report=report)
    last = tried[-1] if tried else {"message": "no attempt"}
    if quick_work is not None:
        return replace(sol, realization_report={
            "status": "not_found", "attempts": tried, "incomplete": True,
            "reason": f"not found in a quick search ({quick_work} work units, the design's "
                      f"own loop and bars); last: {last['message']}"})
    closest = float(np.max(sol.singularity))
    near = "" if not closest < NEAR_SINGULAR else (
        f"every one of the nine loops comes within S = {closest:.1e} of a singular "
        "configuration (generic motions: 1e-6 .. 1), so the motion is nearly degenerate; ")
    report = {"status": "not_found", "attempts": tried,
              "reason": f"{near}no collision-free realization in {len(tried)} attempts (work "
                        f"budgets {FIRST_ATTEMPT_WORK} + {FALLBACK_WORK} each further); last: "
                        f"{last['message']}",
              "advice": ("move the poses apart or choose another mu or family; " if near
                         else "") + "raise realization.max_k, lower rho/d "
                        "(realization.rho_fraction, d_fraction), fix fewer vertices, or choose "
                        "another loop or mu"}
    return replace(sol, realization_report=report)


def attach_end_effector(sol: Solution) -> Any:
    """The design's end-effector polyhedron placed at the reference pose on the chosen loop."""
    from paraloop_core.realization import endeffector as eem

    s = sol.design.end_effector
    if s.mesh is not None:
        body = eem.scaled(eem.load_mesh(mesh_file(sol.design)), s.scale)
    else:
        body = eem.builtin(s.shape, s.scale)
    return eem.attach(body, sol.reference, sol.loop.joint_factors, s.L, s.R)


def solve_to_dict(design: Design, realize: bool = True) -> dict[str, Any]:
    """The result dict of ``design`` (:func:`solve`, :func:`result_to_dict`) in one pure call:
    a task of a batch run, whose input and output cross process boundaries."""
    return result_to_dict(solve(design, realize=realize))
