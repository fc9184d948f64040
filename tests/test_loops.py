"""The nine 6R loops: classification, closure, axes from both chains, joint angles."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings

from paraloop_core.algebra import dq, factor, poly
from paraloop_core.linkage import loops
from tests.conftest import random_cubic, random_rotation_factors, seeds


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


@settings(max_examples=25, deadline=None)
@given(seeds)
def test_cycle_samples_keep_every_joint_turn_small(seed):
    """:func:`loops.cycle_samples`: sorted parameters in [0, 1) holding the uniform grid, and
    between two neighbours (round the cycle) no norm factor turns by more than pi / (n // 3)
    of its angle, however fast the motion passes a factor's root."""
    rng = np.random.default_rng(seed)
    h = random_rotation_factors(rng, 3)
    h[0, :4] *= [1.0, 1e-3, 1e-3, 1e-3]  # a root near the real axis: a fast half turn
    h[0, 4:] *= 1e-3
    jf = loops.loop_joint_factors(factor.all_factorizations(poly.from_factors(h)).factors)[0]
    n = 90
    u = loops.cycle_samples(jf, n)
    assert np.all(np.diff(u) > 0) and u[0] >= 0.0 and u[-1] < 1.0
    assert np.isin(np.arange(n) / n, u).all()
    t = poly.param_to_t(u)
    r = np.linalg.norm(jf[:3, 1:4], axis=-1)
    # each factor's half angle falls from pi (t = -inf, u = 0) to 0 (t = +inf, u -> 1)
    angle = np.arctan2(r[:, None], t[None] - jf[:3, 0, None])
    angle[:, ~np.isfinite(t)] = np.pi
    gaps = np.diff(np.concatenate([angle, np.zeros((3, 1))], axis=1), axis=1)
    assert np.all(np.abs(gaps) <= np.pi / (n // 3) + 1e-9)


def test_cycle_samples_tighten_the_motion_bound_of_a_fast_loop():
    """Where one joint flips within a sliver of u, uniform samples leave one cell whose sound
    motion bound spans the whole flip; the cycle samples bound every cell tightly (the base
    and the verification would otherwise refuse a sound clearance)."""
    from paraloop_core.realization.motion_bound import chain_displacement_bounds

    rng = np.random.default_rng(7)
    h = random_rotation_factors(rng, 3)
    h[0, :4] *= [1.0, 1e-3, 1e-3, 1e-3]
    h[0, 4:] *= 1e-3
    jf = loops.loop_joint_factors(factor.all_factorizations(poly.from_factors(h)).factors)[0]
    uniform = np.arange(360) / 360
    loose = chain_displacement_bounds(jf, 0, 3, np.zeros(3), 1.0, uniform).max()
    tight = chain_displacement_bounds(jf, 0, 3, np.zeros(3), 1.0,
                                      loops.cycle_samples(jf, 360)).max()
    assert tight < 0.2 * loose
