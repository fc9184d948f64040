"""Closest pose on a motion (MATH section 8 (2a), TV12) and proportional spacing (2b)."""

from __future__ import annotations

import numpy as np
import pytest

from paraloop_core.algebra import dq, poly
from paraloop_core.motion import closest, metric
from tests.conftest import TV6_FACTORS, random_cubic


def random_inertia(rng: np.random.Generator, weight: float = 1.0) -> metric.Inertia:
    axes = np.linalg.qr(rng.normal(size=(3, 3)))[0].T
    return metric.Inertia(0.3 * rng.normal(size=3), axes, np.abs(rng.normal(size=3)) + 0.5,
                          weight)


def test_tv12_closest_pose_on_tv6():
    c = poly.from_factors(TV6_FACTORS)
    target = dq.normalize(poly.evaluate(c, 0.5))
    t, d2 = closest.closest_pose(c, target, metric.sphere(1.0))
    assert t == pytest.approx(0.5, abs=1e-9)
    assert d2 == pytest.approx(0.0, abs=1e-18)


def test_quadratic_form_matches_metric():
    rng = np.random.default_rng(1)
    inertia = random_inertia(rng, 1.7)
    m = closest.quadratic_form(inertia)
    g = rng.normal(size=(50, 8))
    got = np.einsum("ni,ij,nj->n", g, m, g) / np.sum(g[:, :4] ** 2, -1)
    np.testing.assert_allclose(got, metric.distance_sq(dq.IDENTITY, g, inertia), rtol=1e-12)


def test_critical_polynomial_degree_and_derivative():
    rng = np.random.default_rng(2)
    c = random_cubic(rng)
    s = dq.study_project(dq.normalize(rng.normal(size=8)))
    inertia = random_inertia(rng)
    num = closest.critical_polynomial(c, s, inertia)
    assert num.shape == (11,)  # degree <= 10
    # num = Q'N - QN' and f' = num / N^2: compare with a central difference of f.
    t, h = 0.37, 1e-6
    f = metric.distance_sq(s, poly.evaluate(c, np.array([t - h, t + h])), inertia)
    n = np.sum(poly.evaluate(c, t)[:4] ** 2)
    assert np.polynomial.polynomial.polyval(t, num) / n**2 == pytest.approx(
        (f[1] - f[0]) / (2 * h), rel=1e-5)


def test_closest_pose_matches_dense_sampling_batched():
    rng = np.random.default_rng(3)
    c = random_cubic(rng, (4,))  # four motions
    s = dq.study_project(dq.normalize(rng.normal(size=(4, 12, 8))))
    inertia = random_inertia(rng, 1.3)
    t, d2 = closest.closest_pose(c[:, None], s, inertia)
    assert t.shape == d2.shape == (4, 12)
    tt = poly.param_to_t(np.linspace(0.0, 1.0, 40001))
    dense = metric.distance_sq(s[..., None, :], poly.evaluate_pose(c[:, None, None], tt), inertia)
    best = dense.min(-1)
    assert np.all(d2 <= best + 1e-9 * (1 + best))  # never worse than sampling
    assert np.all(best - d2 <= 1e-5 * (1 + best))  # and the sampling is close to it
    np.testing.assert_allclose(metric.distance_sq(s, poly.evaluate_pose(c[:, None], t), inertia),
                               d2, rtol=1e-9, atol=1e-12)


def test_closest_pose_at_infinity():
    rng = np.random.default_rng(4)
    c = random_cubic(rng)
    t, d2 = closest.closest_pose(c, dq.IDENTITY, metric.sphere(1.0))
    assert np.isinf(t) and d2 == pytest.approx(0.0, abs=1e-20)


def test_closest_pose_rejects_bad_targets():
    c = poly.from_factors(TV6_FACTORS)
    with pytest.raises(ValueError, match="finite"):
        closest.closest_pose(c, np.full(8, np.nan), metric.sphere(1.0))
    with pytest.raises(ValueError, match="8"):
        closest.closest_pose(c, np.ones(7), metric.sphere(1.0))


def test_proportional_spacing_equalizes_arc_chord_ratios():
    """Eq. 10: the guides split the closed cycle proportionally to the target chords."""
    rng = np.random.default_rng(5)
    c = random_cubic(rng)
    inertia = metric.sphere(1.0)
    targets = dq.normalize(poly.evaluate_pose(c, poly.param_to_t(np.linspace(0, 1, 8)[:-1])))
    targets[1:] = dq.normalize(targets[1:] + 0.05 * rng.normal(size=(6, 8)))
    targets = dq.study_project(targets)
    t1, _ = closest.closest_pose(c, targets[1], inertia)
    t = closest.proportional_params(c, targets, inertia, t1, samples=4096)
    u, s = closest.arc_table(c, inertia, 40000)
    pos = np.interp(poly.t_to_param(t), u, s)
    pos = pos if pos[0] <= s[-1] / 2 else s[-1] - pos
    arcs = np.diff(np.r_[0.0, pos, s[-1]])
    chords = np.sqrt(metric.distance_sq(targets, np.roll(targets, -1, 0), inertia))
    ratios = arcs / chords
    assert np.ptp(ratios) / ratios.mean() < 1e-3
