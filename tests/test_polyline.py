"""Eq. 11 initial polyline (MATH §10)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from paraloop_core.algebra import dq
from paraloop_core.errors import RealizationError
from paraloop_core.linkage import loops
from paraloop_core.realization import polyline
from paraloop_core.validation.table1 import random_loops


def _objective(q, u, s):
    e = q + s[:, None] * u
    return np.sum((e - np.roll(e, -1, axis=0)) ** 2)


@pytest.mark.parametrize("fixed", [None, {0: 0.7}, {1: -0.3, 4: 1.2}])
def test_least_squares_polyline_matches_generic_optimizer(fixed):
    jf = random_loops(3, 2)[1, 0]
    s, e = polyline.shortest_polyline(jf, fixed)
    q, u = polyline.axis_frames(jf)
    assert np.allclose(e, q + s[:, None] * u)
    held = dict(fixed or {})
    cons = [{"type": "eq", "fun": lambda x, i=i, v=v: x[i] - v} for i, v in held.items()]
    res = minimize(lambda x: _objective(q, u, x), np.zeros(6), constraints=cons, tol=1e-14)
    assert _objective(q, u, s) <= res.fun + 1e-9 * max(1.0, res.fun)
    for i, v in held.items():
        assert s[i] == v
    # gradient of the free positions vanishes
    eps = 1e-6
    for i in set(range(6)) - set(held):
        d = np.zeros(6)
        d[i] = eps
        grad = (_objective(q, u, s + d) - _objective(q, u, s - d)) / (2 * eps)
        assert abs(grad) < 1e-6 * (1.0 + _objective(q, u, s))


def test_vertices_lie_on_axes_and_polyline_stays_closed():
    jf = random_loops(5, 1)[0, 1]
    _, e = polyline.shortest_polyline(jf)
    ax = loops.factor_axes(jf)
    assert np.allclose(np.cross(e, ax[:, :3]), ax[:, 3:], atol=1e-12)  # x cross l = m
    t = np.array([-3.0, -0.2, 0.4, 2.5, np.inf])
    pose = loops.link_poses(jf, t)  # (T, 6, 8)
    # E_i is carried by link i (end of segment i) and by link i+1 (start of segment i+1)
    by_i = dq.transform_points(pose, e[None])
    by_next = dq.transform_points(np.roll(pose, -1, axis=1), e[None])
    assert np.allclose(by_i, by_next, atol=1e-9)


def test_length_of_closed_polyline():
    square = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    assert polyline.polyline_length(square) == pytest.approx(4.0)


def test_parallel_axes_are_singular():
    h = np.zeros((6, 8))
    h[:, 3] = 1.0  # all directions along z, distinct points in the plane
    h[:, 5:7] = np.random.default_rng(0).normal(size=(6, 2))
    with pytest.raises(RealizationError) as err:
        polyline.shortest_polyline(h)
    assert err.value.reason == "singular-loop"
    s, _ = polyline.shortest_polyline(h, {2: 0.5})  # one held vertex fixes the slide
    assert np.allclose(s, 0.5)


@pytest.mark.parametrize("fixed", [{6: 0.0}, {-1: 0.0}, {0: np.nan}])
def test_bad_fixed_entries(fixed):
    jf = random_loops(1, 1)[0, 0]
    with pytest.raises(RealizationError) as err:
        polyline.shortest_polyline(jf, fixed)
    assert err.value.reason == "bad-parameters"
