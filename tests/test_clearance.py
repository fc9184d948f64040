"""Exact minimum distance over the cycle (MATH §12) against TV11 and dense sampling."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from paraloop_core.algebra import poly
from paraloop_core.linkage import loops
from paraloop_core.realization import clearance, polyline
from paraloop_core.realization.collision import THIN_PAIRS, polyline_segments
from paraloop_core.validation.table1 import random_loops

K = np.eye(8)[3]
MOVING = np.array([[2.0, -1.0, 0.0], [2.0, 1.0, 0.0]])  # TV11 moving segment under t - k


def sampled_min(motion, fixed, moving, n=20001):
    """Dense sampling of u in (0, 1) plus bounded local refinement (reference, slow)."""
    md = clearance.motion_data(motion[None])

    def dist(u):
        t = poly.param_to_t(np.atleast_1d(u))[None]
        seg = clearance.moving_segments(md, np.zeros(1, int), moving[None], t)[0]
        return clearance.segment_distance(fixed[0], fixed[1], seg[:, 0], seg[:, 1])

    u = np.linspace(0.0, 1.0, n, endpoint=False)
    vals = dist(u)
    i = int(np.argmin(vals))
    res = minimize_scalar(lambda x: dist(x)[0], bounds=(u[i] - 1.0 / n, u[i] + 1.0 / n),
                          method="bounded", options={"xatol": 1e-13})
    return min(float(res.fun), float(vals[i]))


def test_tv11_min_distance():
    fixed = np.array([[3.0, 0.0, 1.0], [3.0, 0.0, -1.0]])
    dist, t = clearance.min_distance(poly.linear(K), fixed, MOVING)
    assert dist == pytest.approx(3.0 - np.sqrt(5.0), abs=1e-12)
    assert abs(t) == pytest.approx(2.0 + np.sqrt(5.0), abs=1e-8)


def test_tv11_contact_distance_is_zero():
    fixed = np.array([[2.1, 0.0, 1.0], [2.1, 0.0, -1.0]])
    dist, t = clearance.min_distance(poly.linear(K), fixed, MOVING)
    assert dist < 1e-12
    assert abs(t) == pytest.approx(np.sqrt(41.0), abs=1e-8)


def test_minimum_at_home_reports_inf():
    # The moving bar passes under the fixed one exactly in its home pose (t = inf).
    fixed = np.array([[2.0, -1.0, 0.5], [2.0, 1.0, 0.5]])
    dist, t = clearance.min_distance(poly.linear(K), fixed, MOVING)
    assert dist == pytest.approx(0.5, abs=1e-12)
    assert np.isinf(t)


def test_batched_shapes():
    fixed = np.array([[[3.0, 0.0, 1.0], [3.0, 0.0, -1.0]]] * 3)
    dist, t = clearance.min_distance(poly.linear(K), fixed, np.stack([MOVING] * 3))
    assert dist.shape == t.shape == (3,)
    with pytest.raises(ValueError):
        clearance.min_distance(poly.linear(K), fixed, MOVING)


@pytest.mark.parametrize("seed", [11, 12])
def test_exact_min_matches_dense_sampling_on_random_loops(seed):
    rng = np.random.default_rng(seed)
    jf = random_loops(seed, 1)[0, seed % 2]
    _, e = polyline.shortest_polyline(jf)
    _, u = polyline.axis_frames(jf)
    # shifted polylines so that some pairs collide and some do not
    segs = polyline_segments(e + rng.normal(scale=0.7, size=(2, 6, 1)) * u)
    for c in range(len(segs)):
        for i, j in THIN_PAIRS:
            motion = loops.relative_motion(jf, i, j)
            exact, _ = clearance.min_distance(motion, segs[c, i], segs[c, j])
            ref = sampled_min(motion, segs[c, i], segs[c, j])
            scale = np.abs(segs[c]).max()
            assert exact <= ref + 1e-9 * scale  # exact is a true minimum ...
            assert ref <= exact + 1e-7 * scale  # ... and no smaller value is missed


def _brute_segment_distance(p0, p1, q0, q1, n=401):
    s = np.linspace(0, 1, n)
    a = p0 + s[:, None] * (p1 - p0)
    b = q0 + s[:, None] * (q1 - q0)
    return np.linalg.norm(a[:, None] - b[None], axis=-1).min()


def test_segment_distance_generic_parallel_degenerate():
    rng = np.random.default_rng(4)
    cases = [rng.normal(size=(4, 3)) for _ in range(20)]
    d = rng.normal(size=3)
    cases.append(np.array([[0, 0, 0], d, [1, 1, 1], np.array([1, 1, 1]) + 2 * d]))  # parallel
    cases.append(np.array([[0, 0, 0], d, d / 2, 3 * d]))  # collinear overlap
    cases.append(np.array([[1.0, 2, 3], [1.0, 2, 3], [0, 0, 0], [2, 2, 2]]))  # point vs segment
    cases.append(np.array([[1.0, 2, 3], [1.0, 2, 3], [0, 1, 0], [0, 1, 0]]))  # point vs point
    got = clearance.segment_distance(*np.stack(cases).transpose(1, 0, 2))
    for c, g in zip(cases, got, strict=True):
        assert g == pytest.approx(_brute_segment_distance(*c), abs=2e-3 * (1 + np.abs(c).max()))
        assert g <= _brute_segment_distance(*c) + 1e-12


def test_real_poly_roots_with_leading_zeros():
    c = np.array([[2.0, -3.0, 1.0, 0.0], [-6.0, 11.0, -6.0, 1.0], [0.0, 0.0, 0.0, 0.0],
                  [5.0, 0.0, 0.0, 0.0]])
    r = poly.real_poly_roots(c, rtol=1e-13)
    assert np.allclose(np.sort(r[0, :2].real), [1.0, 2.0]) and np.isnan(r[0, 2])
    assert np.allclose(np.sort(r[1].real), [1.0, 2.0, 3.0])
    assert np.all(np.isnan(r[2])) and np.all(np.isnan(r[3]))
    assert np.allclose(poly.real_poly_roots(c[1]), r[1])  # default behaviour unchanged


def test_segment_distance_degenerate_segments():
    from paraloop_core.realization.clearance import segment_distance

    seg0, seg1 = np.array([0.0, 0, 0]), np.array([2.0, 0, 0])
    point = np.array([1.0, 1, 0])
    assert np.isclose(segment_distance(seg0, seg1, point, point), 1.0)
    assert np.isclose(segment_distance(point, point, seg0, seg1), 1.0)
    assert np.isclose(segment_distance(point, point, seg0, seg0), np.sqrt(2.0))
