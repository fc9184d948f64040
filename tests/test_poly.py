"""Motion-polynomial arithmetic, evaluation at infinity, division, reparametrization."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings

from paraloop_core.algebra import dq, poly
from tests.conftest import random_cubic, random_rotation_factors, seeds


@settings(max_examples=30, deadline=None)
@given(seeds)
def test_product_evaluates_as_product(seed):
    rng = np.random.default_rng(seed)
    a, b = rng.normal(size=(3, 8)), rng.normal(size=(4, 8))
    t = rng.normal(size=5)
    prod = poly.mul(a, b)
    assert np.allclose(poly.evaluate(prod, t),
                       dq.mul(poly.evaluate(a, t), poly.evaluate(b, t)))


@settings(max_examples=30, deadline=None)
@given(seeds)
def test_norm_is_real_and_matches_product(seed):
    rng = np.random.default_rng(seed)
    c = random_cubic(rng)
    assert poly.is_motion_polynomial(c)
    full = poly.mul(c, poly.conj(c))
    assert np.allclose(full[:, 0], poly.norm_poly(c))
    assert np.allclose(full[:, 1:], 0.0, atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(seeds)
def test_right_division_and_quadratic_remainder(seed):
    rng = np.random.default_rng(seed)
    c = random_cubic(rng)
    h = random_rotation_factors(rng, 1)[0]
    q, r = poly.right_divide_linear(c, h)
    rebuilt = poly.mul(q, poly.linear(h))
    rebuilt[0] += r
    assert np.allclose(rebuilt, c)
    # C = Q M + R with M = t^2 - t + 2 real: the remainder must give back R
    quad = np.zeros((3, 8))
    quad[:, 0] = [2.0, -1.0, 1.0]
    qq, rr = rng.normal(size=(2, 8)), rng.normal(size=(2, 8))
    cc = poly.mul(qq, quad)
    cc[:2] += rr
    assert np.allclose(poly.mod_quadratic(cc, np.array([2.0, -1.0])), rr)


def test_evaluate_at_infinity_and_pose_scaling():
    rng = np.random.default_rng(0)
    c = random_cubic(rng)
    assert np.allclose(poly.evaluate(c, np.inf), c[-1])
    t = np.array([-1e8, -3.0, 0.5, 2.0, 1e9, np.inf])
    pose = poly.evaluate_pose(c, t)
    exact = poly.evaluate(c, t[:-1])
    assert np.allclose(dq.normalize(pose[:-1]), dq.normalize(exact))
    assert np.allclose(dq.normalize(pose[-1]), dq.IDENTITY)
    assert np.all(np.isfinite(poly.evaluate_pose(c, np.array([1e300]))))


def test_param_to_t_round_trip():
    u = np.linspace(0, 1, 11)
    t = poly.param_to_t(u)
    assert np.isinf(t[0]) and np.isinf(t[-1]) and t[5] == 0.0
    assert np.allclose(poly.t_to_param(t[1:-1]), u[1:-1])


def test_reparametrize_and_monic():
    rng = np.random.default_rng(1)
    c = random_cubic(rng)
    r = poly.reparametrize(c, 2.0, -0.5)
    t = rng.normal(size=3)
    assert np.allclose(poly.evaluate(r, t), poly.evaluate(c, 2 * t - 0.5))
    lead = dq.from_pos_wxyz(rng.normal(size=3), rng.normal(size=4))
    mono, got_lead = poly.make_monic(lead * 2.0 * 0 + dq.mul(lead, c))
    assert np.allclose(mono, c) and np.allclose(got_lead, lead)
    with pytest.raises(ValueError, match="a != 0"):
        poly.reparametrize(c, 0.0, 1.0)
    bad = c.copy()
    bad[-1] = [0, 0, 0, 0, 1, 0, 0, 0]
    with pytest.raises(ValueError, match="leading coefficient"):
        poly.make_monic(bad)


def test_as_poly_rejects_bad_input():
    with pytest.raises(ValueError, match="shape"):
        poly.as_poly(np.zeros((3, 7)))
    with pytest.raises(ValueError, match="non-finite"):
        poly.as_poly(np.full((2, 8), np.nan))
