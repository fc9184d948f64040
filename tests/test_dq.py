"""Dual quaternions: known answers TV1-TV3, TV10 and algebraic properties."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings

from paraloop_core.algebra import dq
from tests.conftest import seeds


def test_tv1_tv2_tv3_point_action():
    assert np.allclose(dq.transform_points(np.array([1, -1, 0, 0, 0, 0, 0, 0.0]),
                                           np.array([0, 1, 0.0])), [0, 0, -1])
    assert np.allclose(dq.transform_points(np.array([1, 0, 0, 0, 0, 0.5, 1, 1.5]),
                                           np.zeros(3)), [1, 2, 3])
    assert np.allclose(dq.transform_points(np.array([1, 0, 0, 1, 0, 0, -1, 0.0]),
                                           np.array([2, 0, 0.0])), [1, 1, 0])


def test_tv10_study_projection():
    q = np.array([1, 0, 0, 0, 1, 2, 3, 4.0])
    assert np.allclose(dq.study_project(q), [1, 0, 0, 0, 0, 2, 3, 4])
    s = np.sqrt(0.5)
    q = np.array([s, s, 0, 0, 1, 0, 0, 0.0])
    assert np.allclose(dq.study_project(q)[4:], [0.5, -0.5, 0, 0])
    # idempotent
    assert np.allclose(dq.study_project(dq.study_project(q)), dq.study_project(q))


def _random_poses(rng, n):
    return dq.from_pos_wxyz(rng.normal(size=(n, 3)), rng.normal(size=(n, 4)))


@settings(max_examples=30, deadline=None)
@given(seeds)
def test_composition_and_inverse(seed):
    rng = np.random.default_rng(seed)
    a, b = _random_poses(rng, 2)
    x = rng.normal(size=(5, 3))
    ab = dq.mul(a, b)
    assert np.allclose(dq.transform_points(ab, x),
                       dq.transform_points(a, dq.transform_points(b, x)))
    assert np.allclose(dq.mul(a, dq.inv(a)), dq.IDENTITY)
    assert np.allclose(dq.conj(dq.mul(a, b)), dq.mul(dq.conj(b), dq.conj(a)))
    assert abs(dq.study_residual(ab)) < 1e-12
    # homogeneity: scaled poses act the same
    assert np.allclose(dq.transform_points(3.7 * a, x), dq.transform_points(a, x))


@settings(max_examples=30, deadline=None)
@given(seeds)
def test_conversions_round_trip(seed):
    rng = np.random.default_rng(seed)
    pos, q = rng.normal(size=3), rng.normal(size=4)
    pose = dq.from_pos_wxyz(pos, q)
    p2, q2 = dq.to_pos_wxyz(pose)
    assert np.allclose(p2, pos)
    assert np.allclose(q2, q / np.linalg.norm(q) * np.sign(q[0]))
    mat = dq.to_matrix(pose)
    x = rng.normal(size=(4, 3))
    assert np.allclose(x @ mat[:3, :3].T + mat[:3, 3], dq.transform_points(pose, x))
    assert np.allclose(dq.normalize(dq.from_matrix(mat)), dq.normalize(pose))


@settings(max_examples=30, deadline=None)
@given(seeds)
def test_line_action_matches_point_action(seed):
    rng = np.random.default_rng(seed)
    pose = _random_poses(rng, 1)[0]
    a, b = rng.normal(size=(2, 3))
    line = np.concatenate([b - a, np.cross(a, b - a)])
    moved = dq.transform_lines(pose, line)
    pa, pb = dq.transform_points(pose, np.stack([a, b]))
    assert np.allclose(moved, np.concatenate([pb - pa, np.cross(pa, pb - pa)]))


def test_screw_parameters_recover_rotation_and_translation():
    q = dq.mul(dq.translation([0, 0, 2.0]), dq.rotation_about_line([0, 0, 1], [1, 0, 0], 0.5))
    s = dq.screw_parameters(q)
    assert np.allclose(s["direction"], [0, 0, 1])
    assert np.allclose(s["angle"], 0.5)
    assert np.allclose(s["pitch_distance"], 2.0)
    # the axis passes through (1, 0, 0): moment = point x direction
    assert np.allclose(s["moment"], np.cross([1, 0, 0], [0, 0, 1]))
    t = dq.screw_parameters(dq.translation([3.0, 0, 0]))
    assert np.allclose(t["direction"], [1, 0, 0]) and np.isclose(t["pitch_distance"], 3.0)


def test_batched_equals_per_element():
    rng = np.random.default_rng(3)
    a, b = _random_poses(rng, 6).reshape(2, 3, 8)
    batched = dq.mul(a, b)
    for k in range(3):
        assert np.allclose(batched[k], dq.mul(a[k], b[k]))


def test_bad_input_messages():
    with pytest.raises(ValueError, match="not invertible"):
        dq.inv(np.zeros(8))
    with pytest.raises(ValueError, match="nonzero"):
        dq.from_pos_wxyz(np.zeros(3), np.zeros(4))
    with pytest.raises(ValueError, match=r"\(\.\.\., 8\)"):
        dq.inv(np.zeros(7))


def test_small_and_large_product_paths_agree():
    rng = np.random.default_rng(5)
    a, b = rng.normal(size=(2, 3000, 8))
    big = dq.mul(a, b)  # sliced path
    small = np.stack([dq.mul(a[k], b[k]) for k in range(0, 3000, 300)])  # einsum path
    assert np.allclose(big[::300], small)
    # against the definition with explicit i, j, k rules: i j = k, j k = i, k i = j
    e = np.eye(4)
    assert np.allclose(dq.qmul(e[1], e[2]), e[3]) and np.allclose(dq.qmul(e[2], e[3]), e[1])
    assert np.allclose(dq.qmul(e[3], e[1]), e[2]) and np.allclose(dq.qmul(e[1], e[1]), -e[0])
