"""The nine 6R loops: classification, closure, axes from both chains, joint angles."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings

from paraloop_core.algebra import dq, factor, poly
from paraloop_core.linkage import loops
from tests.conftest import random_cubic, seeds


def test_nine_loops_three_angle_symmetric():
    assert len(loops.LOOP_PAIRS) == 9
    assert sum(loops.LOOP_IS_AS) == 3
    orders = factor.NORM_ORDERS
    for (f, g), is_as in zip(loops.LOOP_PAIRS, loops.LOOP_IS_AS, strict=True):
        assert orders[f][0] != orders[g][0] and orders[f][2] != orders[g][2]
        assert is_as == bool(np.all(orders[g] == orders[f][::-1]))
        if not is_as:  # double Bennett: cyclic shift
            shifts = [np.roll(orders[f], s) for s in (1, 2)]
            assert any(np.all(orders[g] == s) for s in shifts)


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_loop_closure_and_axis_consistency(seed):
    rng = np.random.default_rng(seed)
    c = random_cubic(rng)
    facts = factor.all_factorizations(c)
    jf = loops.loop_joint_factors(facts.factors)  # (9, 6, 8)
    t = np.concatenate([rng.normal(size=4) * 3, [np.inf]])
    poses = loops.link_poses(jf, t)  # (9, T, 6, 8)
    # both chains reach the end link: L_3 = C(t)
    c_t = dq.normalize(poly.evaluate_pose(c, t))
    assert np.allclose(dq.normalize(poses[..., 3, :]), c_t, atol=1e-9)
    # closure: L_4 (t - b2) ∝ C, i.e. the chain b0 b1 b2 also gives C
    l4b2 = dq.mul(poses[..., 4, :], poly.evaluate_pose(poly.linear(jf[:, None, 3, :]), t))
    assert np.allclose(dq.normalize(l4b2), np.broadcast_to(c_t, l4b2.shape), atol=1e-9)
    # each axis A_i is fixed in links i and i+1: same line via both link poses
    home = loops.factor_axes(jf)[:, None]  # (9, 1, 6, 6)
    axes = loops.axes_at(jf, t)
    for i in range(6):
        via_next = dq.transform_lines(poses[..., (i + 1) % 6, :], home[..., i, :])
        assert np.allclose(via_next, axes[..., i, :], atol=1e-8)


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_angle_symmetric_opposite_angles_equal(seed):
    rng = np.random.default_rng(seed)
    facts = factor.all_factorizations(random_cubic(rng))
    jf = loops.loop_joint_factors(facts.factors)
    ang = loops.joint_angles(jf, rng.normal(size=6) * 2)
    for k in np.flatnonzero(loops.LOOP_IS_AS):
        # joints i and i+3 turn by the same amount (opposite sign convention for b factors)
        assert np.allclose(ang[k, :, :3], -ang[k, :, 3:][:, [0, 1, 2]], atol=1e-9)
    assert np.all(ang[..., :3] < 0) and np.all(ang[..., 3:] > 0)


@settings(max_examples=20, deadline=None)
@given(seeds)
def test_relative_motion_matches_link_poses(seed):
    rng = np.random.default_rng(seed)
    facts = factor.all_factorizations(random_cubic(rng))
    jf = loops.loop_joint_factors(facts.factors)[int(rng.integers(9))]
    t = rng.normal(size=3) * 2
    poses = loops.link_poses(jf, t)
    x = rng.normal(size=3)
    for i in range(6):
        for j in range(6):
            if i == j:
                continue
            r = loops.relative_motion(jf, i, j)
            assert r.shape[0] - 1 == min((j - i) % 6, (i - j) % 6)
            rel = dq.mul(dq.inv(poses[:, i]), poses[:, j])
            assert np.allclose(dq.transform_points(poly.evaluate(r, t), x),
                               dq.transform_points(rel, x), atol=1e-8)


def test_relative_motion_rejects_bad_links():
    jf = np.zeros((6, 8))
    with pytest.raises(ValueError, match="distinct"):
        loops.relative_motion(jf, 2, 2)
