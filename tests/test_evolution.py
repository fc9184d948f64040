"""Motion evolution (paper Sec. 4.3, MATH section 8): recovery, stages, loops, bad input."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from paraloop_core.algebra import dq, poly
from paraloop_core.errors import FitError
from paraloop_core.motion import closest, evolution, metric, selection
from paraloop_core.motion import evolution_stages as stages
from tests.conftest import random_rotation_factors

SPHERE = metric.sphere(1.0)


def sampled_targets(seed: int = 5, frame: bool = True):
    """Ten world targets on a known cubic: S_0 = A C(inf) = A, S_i = A C(t_i)."""
    rng = np.random.default_rng(seed)
    h = random_rotation_factors(rng)
    c = poly.from_factors(h)
    poses = dq.normalize(poly.evaluate_pose(c, poly.param_to_t(np.linspace(0, 1, 11)[:-1])))
    a = dq.normalize(dq.study_project(rng.normal(size=8))) if frame else dq.IDENTITY
    return dq.normalize(dq.mul(a, poses)), h


def world_residual(res: evolution.FitResult, targets: np.ndarray) -> float:
    """Summed squared distances of the targets to the world motion at the reported closest t."""
    poses = dq.mul(res.reference, poly.evaluate_pose(res.motion_rel, res.closest_t))
    return float(np.sum(metric.distance_sq(targets, poses, SPHERE)))


def test_four_pose_start_recovers_known_cubic():
    targets, _ = sampled_targets(seed=7)
    settings = evolution.EvolutionSettings(init="four-pose", starts=1)
    res = evolution.fit_motion(targets, SPHERE, settings)
    assert res.cost <= 1e-8 and res.status == "converged"
    assert world_residual(res, targets) <= 1e-8
    np.testing.assert_allclose(res.reference, targets[0], atol=1e-12)
    assert np.isinf(res.closest_t[0]) and res.distances[0] == 0.0
    assert res.winning_start == 0 and res.starts_tried == 1
    assert res.stage_history[-1] == "final"


def test_random_starts_recover_known_cubic_and_steps_descend():
    targets, _ = sampled_targets()
    settings = evolution.EvolutionSettings(starts=20, seed=0)
    world, results = evolution.evolve_starts(targets, SPHERE, settings)
    assert len(results) == 20 and [r.index for r in results] == list(range(20))
    assert min(r.cost_history[-1] for r in results) <= 1e-8
    for r in results:  # every accepted step lowers the frozen-guide objective
        assert all(after <= before for before, after in r.steps)
        assert len(r.steps) == len(r.stage_history)
    best = evolution.best_start(results)
    assert best.cost_history[-1] <= 1e-8


def test_frozen_guides_literal_step_converges_linearly():
    """move_guides=False is MATH 8 literally (t_i frozen): slower, but every step descends."""
    targets, h = sampled_targets(frame=False)
    prob = evolution.Problem(targets, targets, np.arange(10), SPHERE, 1.0)
    rng = np.random.default_rng(0)
    h0 = h + 0.02 * rng.normal(size=h.shape)
    settings = evolution.EvolutionSettings(move_guides=False, max_iterations=40)
    res = stages.evolve_start(prob, settings, h0)
    costs = np.array(res.cost_history)
    assert costs[-1] < 1e-3 * costs[0]
    assert all(after < before for before, after in res.steps)


def test_free_reference_and_unordered_targets():
    targets, _ = sampled_targets(seed=7)
    free = evolution.fit_motion(
        targets, SPHERE,
        evolution.EvolutionSettings(init="four-pose", starts=1, free_reference=True))
    assert free.cost <= 1e-8 and world_residual(free, targets) <= 1e-8
    shuffled = targets[[0, 5, 2, 8, 1, 9, 3, 7, 4, 6]]
    res = evolution.fit_motion(shuffled, SPHERE,
                               evolution.EvolutionSettings(ordered=False, starts=6, seed=1))
    assert res.cost <= 1e-8 and "initial" not in res.stage_history


def test_next_stage_logic():
    s = evolution.EvolutionSettings(tol=1e-4)
    assert stages.next_stage("initial", False, 3.0, 0.5, s) == "initial"
    assert stages.next_stage("initial", True, 3.0, 0.5, s) == "middle"
    assert stages.next_stage("middle", True, 1.5, 0.0, s) == "middle"  # w not yet 1
    assert stages.next_stage("middle", True, 1.0, 1e-3, s) == "middle"
    assert stages.next_stage("middle", True, 1.0, 1e-5, s) == "final"
    assert stages.next_stage("final", True, 1.0, 1e-3, s) == "final"
    assert stages.next_stage("final", True, 1.0, 1e-5, s) == "converged"
    assert stages.next_stage("middle", False, 1.0, 0.5, s) == "initial"  # order broke
    assert stages.next_stage("final", False, 1.0, 1e-5, s) == "initial"
    u = evolution.EvolutionSettings(ordered=False)
    assert stages.next_stage("final", False, 1.0, 1e-3, u) == "final"


def test_cyclic_order():
    t = poly.param_to_t(np.array([0.0, 0.1, 0.3, 0.5, 0.9]))
    assert stages.cyclic_order(t) == 1
    assert stages.cyclic_order(np.r_[t[0], t[:0:-1]]) == -1
    assert stages.cyclic_order(t[[0, 2, 1, 3, 4]]) == 0  # swapped pair
    assert stages.cyclic_order(poly.param_to_t(np.array([0.0, 0.6, 0.1, 0.7, 0.2]))) == 0


def test_start_at_solution_skips_initial_stage_and_order_failure_falls_back():
    targets, h = sampled_targets(frame=False)
    prob = evolution.Problem(targets, targets, np.arange(10), SPHERE, 1.0)
    settings = evolution.EvolutionSettings(max_iterations=40)
    res = stages.evolve_start(prob, settings, h)
    assert res.status == "converged" and res.stage_history[0] == "middle"
    assert res.cost_history[-1] <= 1e-20
    # Same motion, but the targets listed out of their visiting order: never in order.
    swapped = targets[[0, 1, 2, 4, 3, 5, 6, 7, 8, 9]]
    prob = evolution.Problem(swapped, swapped, np.arange(10), SPHERE, 1.0)
    res = stages.evolve_start(prob, settings, h)
    assert res.stage_history[0] == "initial" and res.status in ("unordered", "converged")
    if res.status == "converged":  # it found an ordered motion after leaving 'initial'
        t, _ = closest.closest_pose(evolution.evolve_motion(res), swapped, SPHERE)
        t[0] = np.inf
        assert stages.cyclic_order(t) != 0


def dense_gap_arcs(c, t, direction, inertia, samples=20000):
    """Metric arc ``(m-1,)`` from the closest pose of target i to that of target i+1 walking
    the cycle of ``c`` in ``direction``: chord sum over ``samples`` parameters of the gap (20x
    finer than :func:`stages.loop_gaps`; chord sums grow towards the arc as they refine)."""
    u = poly.t_to_param(t)
    out = []
    for a, b in zip(u[:-1], u[1:], strict=True):
        span = np.mod(direction * (b - a), 1.0)
        uu = np.mod(a + direction * span * np.linspace(0.0, 1.0, samples), 1.0)
        poses = poly.evaluate_pose(c, poly.param_to_t(uu))
        out.append(np.sum(np.sqrt(metric.distance_sq(poses[:-1], poses[1:], inertia))))
    return np.array(out)


def test_loop_phenomenon_detected_and_straightened():
    """Targets on a loop-free cubic; random starts (eq. 9) until one converges onto a motion
    showing the loop phenomenon (Fig. 17) that the modified procedure straightens. Which starts
    loop depends on rounding (BLAS kernels), so the test searches instead of naming a start;
    the loops found are checked against an independent dense arc length."""
    rng = np.random.default_rng(5)
    p, m = rng.normal(size=(2, 3, 3))
    m -= np.sum(p * m, 1, keepdims=True) / np.sum(p * p, 1, keepdims=True) * p
    h = np.concatenate([rng.normal(size=(3, 1)), p, np.zeros((3, 1)), m], 1)
    t_true = np.r_[np.inf, poly.param_to_t(np.linspace(0, 1, 11)[1:-1])]
    targets = dq.normalize(poly.evaluate_pose(poly.from_factors(h), t_true))
    assert stages.loop_gaps(poly.from_factors(h), t_true, 1, targets, SPHERE, 3.0) == ()
    settings = evolution.EvolutionSettings(max_iterations=60, loop_fix=True, virtual=1)
    prob = evolution.Problem(targets, targets, np.arange(10), SPHERE, 1.0)
    guides, real = evolution.with_virtual_targets(targets, SPHERE, 1)
    assert guides.shape == (19, 8) and np.all(guides[real] == targets)
    fix = evolution.Problem(targets, guides, real, SPHERE, 1.0)
    chords = np.sqrt(metric.distance_sq(targets[:-1], targets[1:], SPHERE))
    looped_seen, clean_seen = 0, 0
    for start in range(40):
        r = np.random.default_rng([0, start]).normal(size=(3, 4))
        res = stages.evolve_start(prob, settings, np.c_[r, np.zeros((3, 4))], start)
        if res.status not in ("converged", "stalled"):
            continue
        c = evolution.evolve_motion(res)
        t, _ = closest.closest_pose(c, targets, SPHERE, robust=False)
        t[0] = np.inf
        ratio = dense_gap_arcs(c, t, int(stages.cyclic_order(t)) or 1, SPHERE) / chords
        # detection agrees with the finer arcs (2 % slack for its coarser chord sums)
        assert np.all(ratio[list(res.loops)] > 3.0 * 0.999)
        assert np.all(np.delete(ratio, list(res.loops)) < 3.0 * 1.02)
        clean_seen += not res.loops
        if not res.loops:
            continue
        looped_seen += 1
        fixed = evolution._straighten(prob, fix, settings, res)
        if not fixed.loop_fixed:  # no loop-free motion from this start: left as it was
            assert fixed is res
            continue
        assert fixed.loops == () and fixed.status in ("converged", "stalled")
        assert "loop-fix" in fixed.stage_history and fixed.stage_history[:len(
            res.stage_history)] == res.stage_history  # histories are joined
        assert fixed.cost_history[:len(res.cost_history)] == res.cost_history
        assert len(fixed.cost_history) > len(res.cost_history)
        c = evolution.evolve_motion(fixed)
        t, _ = closest.closest_pose(c, targets, SPHERE, robust=False)
        t[0] = np.inf
        ratio = dense_gap_arcs(c, t, int(stages.cyclic_order(t)) or 1, SPHERE) / chords
        assert np.all(ratio < 3.0 * 1.02)
        break
    else:
        pytest.fail(f"no straightened loop in 40 starts ({looped_seen} looped)")
    assert clean_seen > 0  # detection is not simply always on


def test_interpolate_poses_endpoints_and_midpoint():
    rng = np.random.default_rng(9)
    a, b = dq.study_project(dq.normalize(rng.normal(size=(2, 8))))
    out = evolution.interpolate_poses(a, b, np.array([0.0, 0.5, 1.0]), SPHERE)
    assert metric.distance_sq(out[0], a, SPHERE) < 1e-20
    assert metric.distance_sq(out[2], b, SPHERE) < 1e-20
    half = np.sqrt(metric.distance_sq(a, b, SPHERE)) / 2
    np.testing.assert_allclose(np.sqrt(metric.distance_sq(out[1], [a, b], SPHERE)), half,
                               rtol=0.2)


@pytest.mark.parametrize(
    ("poses", "reason", "match"),
    [
        (np.tile(dq.IDENTITY, (4, 1)), "too-few-poses", "at least 5"),
        (np.r_[sampled_targets()[0][:6], sampled_targets()[0][2:3]], "duplicate-poses",
         "2 and 6 coincide"),
        (np.where(np.arange(8) == 3, np.nan, sampled_targets()[0]), "not-finite",
         "pose 0 has non-finite"),
    ],
)
def test_bad_input_refused(poses, reason, match):
    with pytest.raises(FitError, match=match) as exc:
        evolution.fit_motion(poses, SPHERE, evolution.EvolutionSettings(starts=1))
    assert exc.value.reason == reason


def test_no_convergence_and_settings_validation():
    targets, _ = sampled_targets()
    swapped = targets[[0, 1, 2, 4, 3, 5, 6, 7, 8, 9]]  # listed out of their visiting order
    with pytest.raises(FitError, match="no start") as exc:
        evolution.fit_motion(swapped, SPHERE, evolution.EvolutionSettings(
            starts=2, max_iterations=2))
    assert exc.value.reason == "no-convergence"
    for bad in ({"q": 1.5}, {"init": "nope"}, {"starts": 0}, {"four_pose_indices": (1, 2, 3, 4)}):
        with pytest.raises(ValueError):
            evolution.EvolutionSettings(**bad)


def test_result_dict_and_parallel_workers_match():
    targets, _ = sampled_targets()
    settings = evolution.EvolutionSettings(starts=3, seed=2, workers=2, max_iterations=30)
    progress = []
    res = evolution.fit_motion(targets, SPHERE, settings, lambda f, m: progress.append(f))
    serial = evolution.fit_motion(targets, SPHERE, evolution.EvolutionSettings(
        starts=3, seed=2, workers=1, max_iterations=30))
    assert res.cost == pytest.approx(serial.cost, rel=1e-9)
    assert res.winning_start == serial.winning_start and progress[-1] == 1.0
    d = json.loads(json.dumps(evolution.fit_result_to_dict(res)))
    assert d["targets"][0]["closest_t"] is None and len(d["targets"]) == 10
    assert d["winning_start"] == res.winning_start and d["cost_history"]


def test_validate_evolution_cli_writes_png_csv(tmp_path, capsys):
    from app.cli.main import main

    rc = main(["validate", "evolution", "--starts", "3", "--targets", "6", "--workers",
                                  "1", "--max-iterations", "15", "--quiet",
                                  "--out", str(tmp_path)])
    assert rc == 0
    assert (tmp_path / "fig16.png").stat().st_size > 1000
    rows = (tmp_path / "fig16.csv").read_text().splitlines()
    assert rows[0].startswith("iteration,mean,best_run,worst_run") and len(rows) >= 2
    summary = json.loads((tmp_path / "fig16_summary.json").read_text())
    assert summary["starts"] == 3 and "3 starts on 6 targets" in capsys.readouterr().out


def test_smooth_drive_weight_ranks_towards_smoother_starts():
    targets, _ = sampled_targets(seed=11)
    noisy = dq.normalize(targets + 0.1 * np.random.default_rng(1).normal(size=targets.shape))
    settings = evolution.EvolutionSettings(starts=6, seed=0, max_iterations=30)
    world, results = evolution.evolve_starts(noisy, SPHERE, settings)
    scale = evolution.cost_scale(dq.normalize(dq.mul(dq.conj(world[0]), world)), SPHERE)
    usable = [r for r in results if r.status in ("converged", "stalled") and not r.loops]
    pen = {r.index: float(selection.smooth_drive_scores(poly.from_factors(r.factors))[0])
           for r in usable}
    assert evolution.best_start(results, 0.0, scale) is evolution.best_start(results)
    picks = [evolution.best_start(results, w, scale) for w in (0.0, 1e-3, 0.1, 10.0)]
    cost = [p.cost_history[-1] for p in picks]
    smooth = [pen[p.index] for p in picks]
    # a weighted sum: more weight never raises the penalty nor lowers the cost
    assert all(np.diff(smooth) <= 0) and all(np.diff(cost) >= 0)
    assert smooth[-1] < 0.7 * smooth[0] and cost[-1] > cost[0]  # this case: a real trade-off
    assert smooth[-1] == min(pen.values())
    for p, w in zip(picks, (0.0, 1e-3, 0.1, 10.0), strict=True):  # the winner has the least key
        keys = [r.cost_history[-1] / scale + w * np.log(pen[r.index]) for r in usable]
        assert p.cost_history[-1] / scale + w * np.log(pen[p.index]) == min(keys)
    # fit_motion ranks with the setting (starts are independent of it)
    res = evolution.fit_motion(noisy, SPHERE, replace(settings, smooth_drive=0.1))
    assert res.winning_start == picks[2].index


def test_smooth_drive_setting_validation():
    assert evolution.evolution_settings({"smooth_drive": 0}) == evolution.EvolutionSettings()
    assert evolution.evolution_settings({"smooth_drive": 2.5}).smooth_drive == 2.5
    for bad in (-0.1, float("inf"), True, "1", 2e6):
        with pytest.raises(ValueError, match=r"smooth_drive.*\[0, 1e\+06\]"):
            evolution.evolution_settings({"smooth_drive": bad})
    with pytest.raises(ValueError, match="smooth_drive"):
        evolution.EvolutionSettings(smooth_drive=-1.0)
    with pytest.raises(ValueError, match="scale"):
        evolution.best_start([], 0.1, 0.0)
