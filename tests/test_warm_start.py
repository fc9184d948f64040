"""Warm starts of the realization (a drag step): the previous realization's shifts and offsets
tried alone on a nearby loop, certified like a cold answer; the drag preview's vertices."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from paraloop_core import design as design_mod
from paraloop_core import pipeline
from paraloop_core.design import Pose
from paraloop_core.errors import RealizationError
from paraloop_core.realization import certified, realize
from tests.independent.dense_check import check_result

TV8 = Path(__file__).resolve().parent.parent / "assets" / "designs" / "tv8.json"


def moved(design, i: int, delta) -> design_mod.Design:
    p = design.poses[i]
    pose = Pose(p.position + np.asarray(delta, float), p.wxyz.copy())
    return dataclasses.replace(design, poses=design.poses[:i] + (pose,) + design.poses[i + 1:])


@pytest.fixture(scope="module")
def tv8():
    design = design_mod.load_design(TV8)
    return design, pipeline.solve(design, other_loops=False)


def test_same_loop_warm_start_reproduces_the_cold_answer(tv8):
    _, sol = tv8
    real = sol.realization
    warm = realize.warm_start(sol.loop.joint_factors, real.shifts, real.offsets)
    assert warm is not None and warm.stats["warm_start"] == 1
    assert np.allclose(warm.points, real.points, atol=1e-12)
    assert np.allclose(warm.pair_lower, real.pair_lower, atol=1e-9)
    assert warm.certified_clearance >= 2 * warm.radius


@pytest.mark.parametrize("step", [0.002, 0.01])
def test_warm_realization_of_a_drag_step_is_certified(tv8, step):
    design, sol = tv8
    new = pipeline.solve(moved(design, 3, [step, -step, 0.5 * step]), realize=False)
    warm = pipeline.warm_realization(new, sol)
    assert warm is not None and warm.realization_report["warm_start"]
    assert warm.realization.certified_clearance >= 2 * warm.realization.radius
    # an independent dense computation agrees with the certificate
    rep = check_result(pipeline.result_to_dict(warm))
    assert rep["status"] == "checked" and not rep["disagreements"], rep["disagreements"]
    # the drag preview shows the same vertices
    preview = pipeline.warm_preview(new, sol)
    assert preview is not None and preview.effector is None
    assert np.allclose(preview.points, warm.realization.points, atol=1e-9)


def test_solve_with_hint_is_warm_and_without_is_cold(tv8):
    design, sol = tv8
    step = moved(design, 3, [0.002, 0.0, 0.0])
    warm = pipeline.solve(step, other_loops=False, hint=sol)
    cold = pipeline.solve(step, other_loops=False)
    assert warm.realization_report.get("warm_start") and "warm_start" not in \
        cold.realization_report
    assert cold.realization.certified_clearance >= 2 * cold.realization.radius


def test_a_hint_that_does_not_clear_is_refused(tv8):
    _, sol = tv8
    real = sol.realization
    jf = sol.loop.joint_factors
    found = 0
    for offsets in ([1, 1, 1, 1, 1, 1], [-1, -1, -1, -1, -1, -1], [0, 0, 0, 0, 0, 0]):
        for k in (0, 1, 3):
            shifts = np.full(6, k)
            out = realize.warm_start(jf, shifts, np.array(offsets))
            if out is not None:  # whatever it returns is certified
                found += 1
                assert out.certified_clearance >= 2 * out.radius
    assert found < 9  # some of these patterns collide or fail the clearance
    with pytest.raises(RealizationError):
        realize.warm_start(jf, real.shifts, np.array([2, 0, 0, 0, 0, 0]))


def test_other_loop_or_no_realization_gives_no_warm_start(tv8):
    design, sol = tv8
    other = pipeline.solve(dataclasses.replace(design, loop=(design.loop + 1) % 9),
                           realize=False)
    assert pipeline.warm_realization(other, sol) is None
    assert pipeline.warm_preview(other, sol) is None
    bare = pipeline.solve(design, realize=False)
    assert pipeline.warm_realization(sol, bare) is None


def test_end_effector_drag_preview_moves_the_linkage_and_p():
    shading = TV8.parent / "shading-panel.json"
    design = design_mod.load_design(shading)
    sol = pipeline.solve(design, other_loops=False)
    assert sol.end_effector is not None
    new = pipeline.solve(moved(design, 3, [0.004, -0.002, 0.001]), realize=False)
    preview = pipeline.warm_preview(new, sol)
    assert preview is not None and preview.effector is not None
    link = preview.end_link()  # S_3, L, R, E_3 with L, R on P
    assert np.allclose(link[[0, 3]], preview.points[[6, 7]])
    assert np.allclose(link[1:3], preview.effector.vertices[[preview.effector.L,
                                                              preview.effector.R]])
    # the release certifies the same pattern (when it clears) with P's certificate
    warm = pipeline.warm_realization(new, sol)
    assert warm is not None and warm.end_effector is not None
    assert np.allclose(warm.realization.points, preview.points, atol=1e-9)


def test_a_far_step_previews_a_searched_pattern_that_the_release_certifies(tv8):
    """When the last pattern no longer clears, the preview runs a small uncertified search;
    the release tries that pattern first and certifies it like any answer."""
    design, sol = tv8
    rng = np.random.default_rng(5)
    for _ in range(12):
        new = pipeline.solve(moved(design, 3, 0.24 * rng.normal(size=3)), realize=False)
        if pipeline.warm_realization(new, sol) is None:
            preview = pipeline.warm_preview(new, sol)
            if preview is not None:
                break
    else:
        pytest.fail("no far step needed a preview search")
    assert not (np.array_equal(preview.pattern[0], sol.realization.shifts)
                and np.array_equal(preview.pattern[1], sol.realization.offsets))
    warm = pipeline.warm_realization(new, None, preview.pattern)
    assert warm is not None and warm.realization_report["warm_start"]
    assert np.allclose(warm.realization.points, preview.points, atol=1e-9)
    assert np.array_equal(warm.realization.shifts, preview.pattern[0])
    rep = check_result(pipeline.result_to_dict(warm))
    assert rep["status"] == "checked" and not rep["disagreements"], rep["disagreements"]
    full = pipeline.solve(new.design, other_loops=False, hint=sol, pattern=preview.pattern)
    assert np.array_equal(full.realization.points, warm.realization.points)


def test_consecutive_bar_bounds_are_computed_on_demand_and_sound(tv8):
    _, sol = tv8
    real = sol.realization
    assert "joint_lower" not in vars(real)  # not computed by the certificate
    lower = real.joint_lower
    direct = certified.joint_bounds(real.joint_factors, real.points, real.joint_pairs,
                                  real.length).lower - real.reading_gap
    assert np.allclose(lower, direct, rtol=1e-6, atol=1e-9 * real.length)
    # sound: never above the sampled distance of the two consecutive bars over the cycle
    rep = check_result(pipeline.result_to_dict(sol))
    assert rep["status"] == "checked" and not rep["disagreements"], rep["disagreements"]


def test_a_quick_search_reports_itself_incomplete_and_check_can_stop_a_search(tv8):
    design, _ = tv8
    quick = pipeline.solve(design, other_loops=False, quick_work=1)
    rep = quick.realization_report
    assert quick.realization is None and rep["status"] == "not_found" and rep["incomplete"]
    assert len(rep["attempts"]) == 1 and rep["attempts"][0]["reason"] == "budget"
    enough = pipeline.solve(design, other_loops=False, quick_work=10**6)
    assert enough.realization is not None and "incomplete" not in enough.realization_report

    class Stop(Exception):
        pass

    calls = []

    def check():
        calls.append(1)
        if len(calls) > 3:
            raise Stop

    with pytest.raises(Stop):
        pipeline.solve(design, other_loops=False, check=check)
    assert len(calls) == 4
