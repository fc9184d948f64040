"""Exact thin collision check (MATH §11) against TV11, constructed cases and dense sampling."""

from __future__ import annotations

import numpy as np
import pytest

from paraloop_core.algebra import poly
from paraloop_core.errors import RealizationError
from paraloop_core.linkage import loops
from paraloop_core.realization import clearance, collision, polyline
from paraloop_core.realization.realize import realize
from paraloop_core.validation.table1 import random_loops
from tests.test_clearance import MOVING, K, sampled_min


def _hit(motion, fixed, moving):
    md = clearance.motion_data(np.asarray(motion)[None])
    hit, t = collision.pair_collisions(md, np.zeros(1, int), fixed[None], moving[None])
    return bool(hit[0]), float(t[0])


def test_tv11_hit_at_sqrt41():
    hit, t = _hit(poly.linear(K), np.array([[2.1, 0.0, 1.0], [2.1, 0.0, -1.0]]), MOVING)
    assert hit and abs(t) == pytest.approx(np.sqrt(41.0), abs=1e-9)


def test_tv11_no_hit_beyond_reach():
    hit, t = _hit(poly.linear(K), np.array([[3.0, 0.0, 1.0], [3.0, 0.0, -1.0]]), MOVING)
    assert not hit and np.isnan(t)


@pytest.mark.parametrize("theta", [0.4, 1.9, -2.6])
def test_bars_pass_through_each_other_at_known_t(theta):
    # Bar [1, 3] on the x-axis turns about the z-axis by phi(t) = 2 atan2(-1, t) (factor k);
    # the vertical fixed bar at radius 2 and polar angle theta is met when phi = theta (mod 2pi),
    # i.e. at t = -cot(theta / 2) (MATH §1: t = h0 - |p| cot(phi / 2)).
    moving = np.array([[1.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    c = 2.0 * np.array([np.cos(theta), np.sin(theta)])
    fixed = np.array([[c[0], c[1], -1.0], [c[0], c[1], 1.0]])
    hit, t = _hit(poly.linear(K), fixed, moving)
    assert hit and t == pytest.approx(-1.0 / np.tan(theta / 2.0), rel=1e-9)
    # lifted just above the sweep plane: a near miss, no collision
    hit, _ = _hit(poly.linear(K), fixed + [0.0, 0.0, 1.0 + 1e-6], moving)
    assert not hit


def test_closest_approach_at_home_is_a_hit_only_when_touching():
    # A vertical bar standing on the sweep plane right above the home bar's midpoint: the
    # midpoint is the only point of the turning bar at radius 2, so contact is only at home.
    for z, expect in ((0.0, True), (1e-3, False)):
        fixed = np.array([[2.0, 0.0, z], [2.0, 0.0, z + 1.0]])
        hit, t = _hit(poly.linear(K), fixed, MOVING)
        assert hit == expect
        assert np.isinf(t) if expect else np.isnan(t)
        dist, t_min = clearance.min_distance(poly.linear(K), fixed, MOVING)
        assert dist == pytest.approx(z, abs=1e-12) and np.isinf(t_min)


def test_parallel_bars_always_meeting_lines_fall_back_to_distance():
    # Both bars parallel to the rotation axis: the lines meet (at infinity) for every t,
    # Om == 0, so the exact minimum distance decides.
    moving = np.array([[2.0, 0.0, -1.0], [2.0, 0.0, 1.0]])
    touching = np.array([[0.0, 2.0, 0.5], [0.0, 2.0, 3.0]])  # overlaps in z on the sweep
    hit, t = _hit(poly.linear(K), touching, moving)
    assert hit and t == pytest.approx(-1.0 / np.tan(np.pi / 4.0), abs=1e-7)
    separate = touching + [0.0, 0.0, 2.5]  # same circle, no overlap in z
    assert not _hit(poly.linear(K), separate, moving)[0]
    outside = np.array([[0.0, 2.5, -0.5], [0.0, 2.5, 0.5]])
    assert not _hit(poly.linear(K), outside, moving)[0]


@pytest.mark.parametrize("seed", [21, 22, 23])
def test_thin_check_matches_dense_sampling_on_random_loops(seed):
    rng = np.random.default_rng(seed)
    jf = random_loops(seed, 1)[0, seed % 2]
    _, e = polyline.shortest_polyline(jf)
    _, u = polyline.axis_frames(jf)
    free = realize(jf).thin  # collision-free by the search: both outcomes are exercised
    polys = np.concatenate([e + rng.normal(scale=0.6, size=(2, 6, 1)) * u, free[None]])
    got = collision.check_polylines(jf, polys)
    assert not got[-1]
    segs = collision.polyline_segments(polys)
    for c in range(len(polys)):
        hits = []
        for i, j in collision.THIN_PAIRS:
            motion = loops.relative_motion(jf, i, j)
            ref = sampled_min(motion, segs[c, i], segs[c, j], n=4001)
            size = np.linalg.norm(np.ptp(segs[c].reshape(-1, 3), axis=0))
            hits.append(ref < 1e-7 * size)
            assert _hit(motion, segs[c, i], segs[c, j])[0] == hits[-1]
        assert got[c] == any(hits)


def test_batch_equals_single_and_collision_free_exists():
    jf = random_loops(2, 1)[0, 0]
    _, e = polyline.shortest_polyline(jf)
    _, u = polyline.axis_frames(jf)
    polys = e + np.random.default_rng(2).normal(scale=0.5, size=(12, 6, 1)) * u
    polys = np.concatenate([polys, realize(jf).thin[None]])
    batch = collision.check_polylines(jf, polys)
    single = np.array([collision.check_polylines(jf, p) for p in polys])
    assert np.array_equal(batch, single)
    assert batch.any() and not batch.all()


def test_bad_input():
    with pytest.raises(RealizationError) as err:
        collision.check_polylines(np.zeros((5, 8)), np.zeros((6, 3)))
    assert err.value.reason == "bad-parameters"
