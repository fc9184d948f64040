"""Singularity proximity (MATH section 9): TV13, Cauchy-Binet, congruences, cycle minimum."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings

from paraloop_core.algebra import dq, factor, poly
from paraloop_core.linkage import loops, singularity
from tests.conftest import TV6_FACTORS, random_cubic, random_rotation_factors, seeds


def brute_minors(j: np.ndarray) -> float:
    sub = itertools.combinations(range(6), 5)
    return sum(np.linalg.det(j[np.ix_(r, c)]) ** 2
               for r, c in itertools.product(list(sub), repeat=2))


def e5_svd(j: np.ndarray) -> np.ndarray:
    sv2 = np.linalg.svd(j, compute_uv=False) ** 2
    return sum(np.prod(np.delete(sv2, i, axis=-1), axis=-1) for i in range(6))


def nine_loops(c: np.ndarray) -> np.ndarray:
    return loops.loop_joint_factors(factor.all_factorizations(c).factors)


def test_tv13_angle_symmetric_loop_of_tv6():
    tv6 = poly.from_factors(TV6_FACTORS)
    g = factor.factorize(tv6, [2, 1, 0])  # norm order (9, 4, 1)
    jf = np.concatenate([TV6_FACTORS, g[::-1]])
    s = singularity.singularity_curve(jf, np.array([0.0, 1e9, np.inf]))
    assert s[0] == pytest.approx(0.112462115929, rel=1e-10)
    # TV13's "S(inf)" was evaluated at t = 1e9 in check_09; the exact home value differs by
    # O(1/t): S(inf) = 0.124314095359 (agrees with an SVD of loops.axes_at at inf).
    assert s[1] == pytest.approx(0.124314096802, rel=1e-10)
    assert s[2] == pytest.approx(0.124314095359, rel=1e-10)


@settings(max_examples=20, deadline=None)
@given(seeds)
def test_cauchy_binet(seed):
    j = np.random.default_rng(seed).normal(size=(4, 6, 6))
    s = singularity.minors_sq_sum(j)
    assert np.allclose(s, e5_svd(j), rtol=1e-10)
    assert s[0] == pytest.approx(brute_minors(j[0]), rel=1e-10)


def test_reduced_minors_with_special_end_rows():
    # rows 0 and 5 parallel (c = 0), antiparallel, orthogonal, and a rank-4 matrix
    rng = np.random.default_rng(3)
    j = rng.normal(size=(5, 6, 6))
    j[0, 5] = 2.5 * j[0, 0]
    j[1, 5] = -j[1, 0]
    j[2, 5] = np.r_[0.0, 0, 0, 0, 0, 1]
    j[2, 0] = np.r_[1.0, 0, 0, 0, 0, 0]
    j[3] = rng.normal(size=(6, 4)) @ rng.normal(size=(4, 6))
    s = singularity.minors_sq_sum(j)
    assert np.allclose(s, e5_svd(j), rtol=1e-10, atol=1e-12)
    assert s[0] == pytest.approx(brute_minors(j[0]), rel=1e-10)
    assert s[3] < 1e-20


def test_curve_across_chunks_matches_svd():
    # more than one chunk of loops and of parameters in the batched evaluation
    jf = nine_loops(random_cubic(np.random.default_rng(11)))
    t = poly.param_to_t(np.linspace(0.0, 1.0, 2 * singularity._CHUNK + 7))
    expected = e5_svd(loops.axes_at(jf, t))
    assert np.allclose(singularity.singularity_curve(jf, t), expected, rtol=1e-9, atol=1e-15)


def test_linear_congruence_gives_zero():
    rng = np.random.default_rng(2)
    # six lines meeting the two skew lines x-axis and (z = 1, direction y)
    x = np.c_[rng.normal(size=6), np.zeros((6, 2))]
    y = np.c_[np.zeros(6), rng.normal(size=6), np.ones(6)]
    d = y - x
    h = np.zeros((6, 8))
    h[:, 0] = rng.normal(size=6)
    h[:, 1:4] = d
    h[:, 5:8] = np.cross(x, d)
    assert singularity.singularity_curve(h, np.array([np.inf]))[0] < 1e-24
    assert singularity.minors_sq_sum(loops.factor_axes(h)) < 1e-24


def test_planar_loop_identically_zero():
    rng = np.random.default_rng(8)
    h = np.zeros((3, 8))
    h[:, 0] = rng.normal(size=3)
    h[:, 3] = rng.uniform(0.5, 2.0, size=3)  # axes parallel to z
    h[:, 5:8] = np.cross(np.c_[rng.normal(size=(3, 2)), np.zeros(3)], h[:, 1:4])
    jf = nine_loops(poly.from_factors(h))
    s_min, _ = singularity.singularity_min(jf)
    assert np.all(s_min < 1e-20)


@settings(max_examples=10, deadline=None)
@given(seeds)
def test_curve_matches_axes_at_and_min_beats_dense_scan(seed):
    rng = np.random.default_rng(seed)
    jf = nine_loops(random_cubic(rng))
    t = np.r_[np.inf, rng.normal(size=3) * 3, 1e6, -1e3]
    expected = e5_svd(loops.axes_at(jf, t))
    assert np.allclose(singularity.singularity_curve(jf, t), expected, rtol=1e-9, atol=1e-15)
    s_min, t_min = singularity.singularity_min(jf)
    assert np.allclose(singularity.singularity_curve(jf, t_min[:, None])[:, 0], s_min,
                       rtol=1e-9)
    dense = singularity.singularity_curve(jf, poly.param_to_t(np.linspace(0, 1, 4001)))
    # as low as a 4000-point scan up to the documented accuracy (random cubics: no misses
    # measured; a margin for a sharp dip between samples)
    assert np.all(s_min <= dense.min(axis=-1) + 5e-3 * np.median(dense, axis=-1))


def test_sharp_dip_of_a_higher_sampled_minimum_is_refined():
    # loop 7: a dip to S = 8.07 whose sampled local minimum (265) is only the loop's 4th lowest
    jf = nine_loops(random_cubic(np.random.default_rng(21100)))[7]
    s_min, _ = singularity.singularity_min(jf)
    dense = singularity.singularity_curve(jf, poly.param_to_t(np.linspace(0, 1, 100001)))
    assert s_min <= dense.min() * (1 + 1e-3)


def test_min_accuracy_on_fixed_cubics():
    for seed in range(8):
        jf = nine_loops(random_cubic(np.random.default_rng(seed)))
        s_min, _ = singularity.singularity_min(jf)
        dense = singularity.singularity_curve(jf, poly.param_to_t(np.linspace(0, 1, 20001)))
        assert np.all(s_min <= dense.min(axis=-1) * (1 + 1e-6))


def test_frame_dependence():
    rng = np.random.default_rng(6)
    jf = random_rotation_factors(rng, 6)
    t = np.array([np.inf, 0.3, -2.0])
    s = singularity.singularity_curve(jf, t)
    rot = dq.rotation_about_line([0.3, -1.0, 2.0], [0.0, 0.0, 0.0], 0.8)  # about the origin
    moved = dq.mul(dq.mul(rot, jf), dq.inv(rot))
    assert np.allclose(singularity.singularity_curve(moved, t), s, rtol=1e-10)
    scaled = jf * np.r_[np.ones(4), np.full(4, 2.5)]  # lengths x 2.5
    assert np.allclose(singularity.singularity_curve(scaled, t, length=2.5), s, rtol=1e-10)


def test_validation():
    jf = random_rotation_factors(np.random.default_rng(1), 6)
    with pytest.raises(ValueError, match="shape"):
        singularity.singularity_curve(jf[:5], np.array([0.0]))
    with pytest.raises(ValueError, match="without NaN"):
        singularity.singularity_curve(jf, np.array([0.0, np.nan]))
    bad = jf.copy()
    bad[2, 1:4] = 0.0
    with pytest.raises(ValueError, match="no rotation axis"):
        singularity.singularity_min(bad)
    with pytest.raises(ValueError, match="length"):
        singularity.singularity_min(jf, length=0.0)
    with pytest.raises(ValueError, match="samples"):
        singularity.singularity_min(jf, samples=2)
