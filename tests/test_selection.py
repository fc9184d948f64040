"""Selection criteria of a four-pose family (paper Sec. 4.2): scores, exact closest pose, scan."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings

from paraloop_core.algebra import dq, factor, poly
from paraloop_core.errors import InterpolationError
from paraloop_core.linkage import drive, loops
from paraloop_core.motion import fourpose, metric, selection
from tests.conftest import random_rotation_factors, seeds
from tests.test_fourpose import world_poses_on_cubic

SPHERE = metric.sphere(1.0)


@pytest.fixture(scope="module")
def fams() -> fourpose.FourPoseFamilies:
    return fourpose.four_pose_families(world_poses_on_cubic(np.random.default_rng(3)))


def dense_thetas(fams: fourpose.FourPoseFamilies, family: int, n: int) -> np.ndarray:
    return fams.c[family, 0] + np.tan(np.linspace(-np.pi / 2, np.pi / 2, n + 2)[1:-1])


def extra_pose_case(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``(score, dense)`` ``(3,)`` of two random extra poses for three mu: exact score and a
    20001-sample scan of the world motion (an upper bound, coarse for large motions)."""
    rng = np.random.default_rng(seed)
    fams = fourpose.four_pose_families(world_poses_on_cubic(rng))
    extra = dq.from_pos_wxyz(rng.normal(size=(2, 3)), rng.normal(size=(2, 4)))
    inertia = metric.Inertia(rng.normal(size=3), np.eye(3), rng.uniform(0.2, 2, size=3), 1.5)
    mus = np.array([np.inf, 0.3, -2.0])
    score = selection.score_mu(fams, 0, mus, "extra-poses", poses=extra, inertia=inertia)
    world = dq.mul(poly.evaluate_pose(fourpose.world_motion(
        fams.poses[0], fourpose.four_pose_motion_batch(fams, 0, mus))[:, None],
        poly.param_to_t(np.linspace(0, 1, 20001))), fams.poses[0])  # (M, U, 8) world poses
    dense = metric.distance_sq(extra[:, None, None], world, inertia).min(axis=-1).sum(0)
    ok = np.isfinite(score)
    return score[ok], dense[ok]


@settings(max_examples=10, deadline=None)
@given(seeds)
def test_extra_pose_score_vs_dense_sampling(seed):
    score, dense = extra_pose_case(seed)
    assert np.all(score <= dense + 1e-10)
    assert np.all(score >= 0.5 * dense)  # the scan is coarse for large motions, not wrong


def test_extra_pose_hard_cases():
    # regressions: a real critical point at t = -708 (tiny leading coefficient), clustered
    # critical points (roots off by 1e-3), visiting parameters ~1e4 (roots lost)
    for seed in (6968, 75, 18):
        score, dense = extra_pose_case(seed)
        assert np.all(score <= dense + 1e-10)


def test_scores_shapes_and_excluded_mu(fams):
    mus = np.array([np.inf, 1.0, fams.t[0, 1], 0.25, -3.0])
    for crit, params in [("length", {"inertia": SPHERE}),
                         ("base-axes", {"points": np.zeros((2, 3)), "loop": 4}),
                         ("end-axes", {"points": np.ones((2, 3)), "weights": [1.0, 0.0]}),
                         ("extra-poses", {"poses": fams.poses[1:2], "inertia": SPHERE})]:
        s = selection.score_mu(fams, 0, mus, crit, **params)
        assert s.shape == (5,)
        assert np.all(np.isinf(s[1:3])) and np.all(np.isfinite(s[[0, 3, 4]]))
    # the family interpolates its own poses, so they are no extra cost
    s = selection.score_mu(fams, 1, mus[[0, 3]], "extra-poses", poses=fams.poses, inertia=SPHERE)
    assert np.all(s < 1e-12)


def test_best_length_no_worse_than_dense_scan(fams):
    for family in (0, 1):
        mu, score = selection.best_mu(fams, family, "length", inertia=SPHERE)
        dense = selection.score_mu(fams, family, dense_thetas(fams, family, 2000), "length",
                                   inertia=SPHERE)
        assert score <= dense.min() * (1 + 1e-9)
        check = selection.score_mu(fams, family, np.array([np.inf if mu is None else mu]),
                                   "length", inertia=SPHERE)
        assert check[0] == pytest.approx(score, rel=1e-12)


def test_axis_criterion_moves_axes_toward_points(fams):
    points = np.array([[1.0, -2.0, 0.5], [0.0, 3.0, -1.0]])
    for crit, idx in (("base-axes", [0, 5]), ("end-axes", [2, 3])):
        mus = dense_thetas(fams, 0, 64)
        scores = selection.score_mu(fams, 0, mus, crit, points=points, loop=7)
        mu, score = selection.best_mu(fams, 0, crit, points=points, loop=7)
        assert score <= np.min(scores) and score < np.median(scores[np.isfinite(scores)])
        # the score is the sum of squared distances of the chosen loop's axes at home
        c = fourpose.four_pose_motion(fams, 0, mu)
        m = fourpose.world_motion(fams.poses[0], c)
        jf = loops.loop_joint_factors(factor.all_factorizations(m).factors)[7]
        ax = loops.factor_axes(jf[idx])
        d2 = np.sum((np.cross(points, ax[:, :3]) - ax[:, 3:]) ** 2)
        assert d2 == pytest.approx(score, rel=1e-9)


def test_extra_pose_recovers_generating_mu(fams):
    mu0 = 0.37
    c = fourpose.four_pose_motion(fams, 1, mu0)
    m = fourpose.world_motion(fams.poses[0], c)
    extra = dq.normalize(dq.mul(poly.evaluate(m, 0.9), fams.poses[0]))  # world pose at t = 0.9
    mu, score = selection.best_mu(fams, 1, "extra-poses", poses=extra[None], inertia=SPHERE)
    assert score < 1e-12
    assert mu == pytest.approx(mu0, abs=1e-6)


def test_parameter_validation(fams):
    mus = np.array([0.0])
    with pytest.raises(ValueError, match="unknown criterion"):
        selection.score_mu(fams, 0, mus, "shortest")
    with pytest.raises(ValueError, match="unexpected"):
        selection.score_mu(fams, 0, mus, "length", inertia=SPHERE, points=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="needs inertia"):
        selection.score_mu(fams, 0, mus, "length")
    with pytest.raises(ValueError, match="points"):
        selection.score_mu(fams, 0, mus, "base-axes", points=np.zeros(3))
    with pytest.raises(ValueError, match="loop"):
        selection.score_mu(fams, 0, mus, "end-axes", points=np.zeros((2, 3)), loop=9)
    with pytest.raises(ValueError, match="poses"):
        selection.score_mu(fams, 0, mus, "extra-poses", poses=np.zeros((1, 7)), inertia=SPHERE)
    with pytest.raises(ValueError, match="family"):
        selection.best_mu(fams, 2, "length", inertia=SPHERE)
    with pytest.raises(InterpolationError):
        fourpose.four_pose_motion_batch(fams, 0, np.array([1.0]))


def grid_penalty(fams: fourpose.FourPoseFamilies, family: int, loop: int, n: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """``(mus, penalty)`` of the generic cubics on a dense grid, straight from the motor x
    joint table of :func:`drive.peak_speed_ratios` (no selection code)."""
    mus = dense_thetas(fams, family, n)
    mus = mus[~fourpose.bad_mu_mask(fams, family, mus)]
    facts = factor.all_factorizations_batch(fourpose.four_pose_motion_batch(fams, family, mus))
    ok = facts.code == 0
    jf = loops.loop_joint_factors(facts.factors[ok])[:, loop]
    return mus[ok], drive.peak_speed_ratios(jf).max(axis=-1).min(axis=-1)


def test_smooth_drive_picks_the_smoothest_mu(fams):
    loop = 4
    for family in (0, 1):
        mu, score = selection.best_mu(fams, family, "smooth-drive", loop=loop)
        _, dense = grid_penalty(fams, family, loop, 4000)
        assert 1.0 <= score <= dense.min() * (1 + 1e-9)
        # smoother than mu = inf and the shortest motion's mu
        mu_len, _ = selection.best_mu(fams, family, "length", inertia=SPHERE)
        other = selection.score_mu(fams, family, np.array([np.inf, mu_len]), "smooth-drive",
                                   loop=loop)
        assert score <= other.min()
        # the score is the worst joint's peak / mean speed with the best motor, checked by
        # sampling each motor's speeds (drive.constant_speed) in the world frame
        world = fourpose.world_motion(fams.poses[0], fourpose.four_pose_motion(fams, family, mu))
        jf = loops.loop_joint_factors(factor.all_factorizations(world).factors)[loop]
        worst = [drive.constant_speed(jf, m, 1.0).peak_speed_ratio.max() for m in range(6)]
        assert min(worst) == pytest.approx(score, rel=1e-9)
        # a fixed motor scores that motor's worst joint on the chosen loop
        fixed = selection.score_mu(fams, family, np.array([mu]), "smooth-drive", loop=loop,
                                   motor=2)
        assert fixed[0] == pytest.approx(worst[2], rel=1e-9)
    mu, score = selection.best_mu(fams, 0, "smooth-drive", loop=loop)  # this case: much lower
    assert score < 0.5 * selection.score_mu(fams, 0, np.array([np.inf]), "smooth-drive")[0]
    # with the best motor, every loop has the same penalty (each carries every norm root twice)
    per_loop = [selection.score_mu(fams, 0, np.array([mu]), "smooth-drive", loop=k)[0]
                for k in range(9)]
    np.testing.assert_allclose(per_loop, score, rtol=1e-9)


def test_smooth_drive_non_generic_scores_inf():
    # seed 14, family 1: an interval of mu whose cubic has a real norm root (not factorable)
    fams14 = fourpose.four_pose_families(world_poses_on_cubic(np.random.default_rng(14)))
    mus = dense_thetas(fams14, 1, 4000)
    mus = mus[~fourpose.bad_mu_mask(fams14, 1, mus)]
    code = factor.all_factorizations_batch(fourpose.four_pose_motion_batch(fams14, 1, mus)).code
    assert (code != 0).sum() > 10 and (code == 0).sum() > 10
    s = selection.score_mu(fams14, 1, mus, "smooth-drive", loop=3)
    assert np.all(np.isinf(s[code != 0])) and np.all(np.isfinite(s[code == 0]))
    mu, score = selection.best_mu(fams14, 1, "smooth-drive", loop=3)
    assert np.isfinite(score) and score >= 1.0
    # batches mixing generic and non-generic cubics (repeated / translational factor)
    h = random_rotation_factors(np.random.default_rng(0))
    trans = h.copy()
    trans[1, 1:4] = 0.0
    cubics = np.stack([poly.from_factors(h), poly.from_factors(h[[0, 0, 1]]),
                       poly.from_factors(trans)])
    pen, code = selection.smooth_drive_scores(cubics, loop=5, motor=1)
    assert np.isfinite(pen[0]) and np.all(np.isinf(pen[1:])) and np.all(code[1:] != 0)
    assert pen[0] == pytest.approx(drive.smooth_drive_penalty(
        loops.loop_joint_factors(factor.all_factorizations(cubics[0]).factors)[5], 1))
    one, one_code = selection.smooth_drive_scores(cubics[2])
    assert one.shape == () and np.isinf(one) and one_code != 0


def test_smooth_drive_parameter_validation(fams):
    mus = np.array([0.0])
    for bad, match in (({"loop": 9}, "loop"), ({"loop": True}, "loop"), ({"motor": 6}, "motor"),
                       ({"motor": True}, "motor"), ({"inertia": SPHERE}, "unexpected")):
        with pytest.raises(ValueError, match=match):
            selection.score_mu(fams, 0, mus, "smooth-drive", **bad)
