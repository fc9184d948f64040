"""Object-dependent metric (eq. 8): TV9, exactness, invariance, inertia from bodies."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings

from paraloop_core.algebra import dq
from paraloop_core.motion import metric
from tests.conftest import random_cubic, seeds

ID = dq.IDENTITY


def test_tv9_unit_sphere():
    s = metric.sphere(1.0)
    assert np.isclose(metric.distance_sq(ID, dq.translation([1.0, 0, 0]), s), 1.0)
    rz = np.array([np.sqrt(0.5), 0, 0, np.sqrt(0.5), 0, 0, 0, 0])
    assert np.isclose(metric.distance_sq(ID, rz, s), 4 / 3)
    assert np.isclose(metric.distance_sq(ID, rz, metric.sphere(1.0, [1.0, 0, 0])), 10 / 3)


def _random_inertia(rng):
    axes = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    return metric.Inertia(rng.normal(size=3), axes, np.abs(rng.normal(size=3)) + 0.1,
                          float(rng.uniform(0.5, 2)))


@settings(max_examples=30, deadline=None)
@given(seeds)
def test_closed_form_equals_vertex_mean_and_is_left_invariant(seed):
    rng = np.random.default_rng(seed)
    inertia = _random_inertia(rng)
    a, b, g = dq.from_pos_wxyz(rng.normal(size=(3, 3)), rng.normal(size=(3, 4)))
    v = inertia.vertices
    brute = np.mean(np.sum((dq.transform_points(a, v) - dq.transform_points(b, v)) ** 2, -1))
    assert np.isclose(metric.distance_sq(a, 2.5 * b, inertia), brute)
    assert np.isclose(metric.distance_sq(dq.mul(g, a), dq.mul(g, b), inertia), brute)
    assert np.isclose(metric.distance_sq(b, a, inertia), brute)


def test_weight_scales_orientation_only():
    s = metric.sphere(1.0)
    trans = dq.translation([0.3, 0, 0])
    assert np.isclose(metric.distance_sq(ID, trans, s.with_weight(3.0)),
                      metric.distance_sq(ID, trans, s))
    rz = dq.rotation_about_line([0, 0, 1], [0, 0, 0], 0.4)
    assert np.isclose(metric.distance_sq(ID, rz, s.with_weight(3.0)),
                      9 * metric.distance_sq(ID, rz, s))


def test_inertia_from_mesh_is_exact_mean_squared_displacement():
    box = trimesh.creation.box(extents=[2.0, 1.0, 0.5])
    box.apply_translation([0.3, -0.2, 1.0])
    inertia = metric.inertia_from_mesh(box.vertices, box.faces)
    assert np.allclose(inertia.center, [0.3, -0.2, 1.0])
    # mean squared displacement of the solid under a pose, by dense volume sampling
    rng = np.random.default_rng(0)
    pts = rng.uniform(-0.5, 0.5, size=(40000, 3)) * [2.0, 1.0, 0.5] + [0.3, -0.2, 1.0]
    pose = dq.from_pos_wxyz(rng.normal(size=3), rng.normal(size=4))
    msd = np.mean(np.sum((dq.transform_points(pose, pts) - pts) ** 2, -1))
    assert np.isclose(metric.distance_sq(ID, pose, inertia), msd, rtol=0.03)
    # the point-set version agrees with the covariance definition
    pi = metric.inertia_from_points(pts)
    assert np.allclose(np.sort(pi.semi_axes), np.sort(inertia.semi_axes), rtol=0.03)


def test_motion_length_converges_and_batches():
    rng = np.random.default_rng(4)
    c = random_cubic(rng, (3,))
    s = metric.sphere(1.0)
    coarse, fine = metric.motion_length(c, s, 256), metric.motion_length(c, s, 4096)
    assert np.all(coarse <= fine + 1e-12)  # chord sums approach from below
    assert np.allclose(coarse, fine, rtol=1e-3)
    assert np.isclose(metric.motion_length(c[1], s, 256), coarse[1])


def test_bad_inertia_rejected():
    with pytest.raises(ValueError, match="orthonormal"):
        metric.Inertia(np.zeros(3), np.ones((3, 3)), np.ones(3))
    with pytest.raises(ValueError, match="semi-axes"):
        metric.Inertia(np.zeros(3), np.eye(3), np.zeros(3))
    with pytest.raises(ValueError, match="weight"):
        metric.Inertia(np.zeros(3), np.eye(3), np.ones(3), -1.0)
    with pytest.raises(ValueError, match="watertight"):
        metric.inertia_from_mesh(np.eye(3), np.array([[0, 1, 2]]))
