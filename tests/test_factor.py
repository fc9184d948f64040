"""HSS13a factorization, Bennett flips, six factorizations: TV4-TV7 and properties."""

from __future__ import annotations

from fractions import Fraction as Fr

import numpy as np
import pytest
from hypothesis import given, settings

from paraloop_core.algebra import factor, poly
from paraloop_core.errors import NonGenericMotionError
from paraloop_core.linkage import loops
from tests.conftest import TV6_FACTORS, E, random_cubic, random_rotation_factors, seeds


def dqv(p=(0, 0, 0, 0), d=(0, 0, 0, 0)):
    """Exact-fraction DQ as float array."""
    return np.array([float(Fr(x)) for x in (*p, *d)])


def test_tv4_axis_angle_norm():
    h = dqv((2, 0, 0, 3), (0, 1, 1, 0))
    axis = loops.factor_axes(h)
    assert np.allclose(axis[:3], [0, 0, 1])
    foot = np.cross(axis[:3], axis[3:])
    assert np.allclose(foot, [-1 / 3, 1 / 3, 0])
    assert np.allclose(poly.norm_poly(poly.linear(h)), [13, -4, 1])
    jf = np.tile(h, (6, 1))
    ang = loops.joint_angles(jf, np.array([2.0, 5.0]))[:, 0]
    assert np.allclose(ang, [-np.pi, -np.pi / 2])


def test_tv5_bennett_flip_exact():
    h1, h2 = E[1], 2 * E[2] + E[5]
    k1, k2 = factor.bennett_flip(h1, h2)
    assert np.allclose(k1, dqv((0, "8/5", "6/5", 0), (0, "9/25", "-12/25", 0)))
    assert np.allclose(k2, dqv((0, "-3/5", "4/5", 0), (0, "16/25", "12/25", 0)))
    # flip is an involution and the product is preserved
    assert np.allclose(np.stack(factor.bennett_flip(k1, k2)), np.stack([h1, h2]))
    c = poly.from_factors(np.stack([h1, h2]))
    assert np.allclose(poly.from_factors(np.stack([k1, k2])), c)
    # HSS with norm order (t^2 + 4, t^2 + 1) gives the same factors
    assert np.allclose(factor.factorize(c, [1, 0]), np.stack([k1, k2]))


def test_tv6_coefficients_and_factorizations(tv6):
    expected = [[6, 0, 0, 0, 0, 2, -2, 3], [0, 6, -3, 2, -4, 0, -3, -1],
                [0, -1, -2, -3, 0, -2, -1, 0], [1, 0, 0, 0, 0, 0, 0, 0]]
    assert np.allclose(tv6, expected)
    assert np.allclose(poly.norm_poly(tv6), [36, 0, 49, 0, 14, 0, 1])
    orders = {  # norm labels A = t^2+1, B = t^2+4, C = t^2+9
        (0, 2, 1): [dqv((0, 1, 0, 0)),
                    dqv((0, 0, "36/13", "15/13"), (0, "23/13", "25/169", "-60/169")),
                    dqv((0, 0, "-10/13", "24/13"), (0, "3/13", "144/169", "60/169"))],
        (1, 2, 0): [dqv((0, "8/5", "6/5", 0), (0, "9/25", "-12/25", 0)),
                    dqv((0, "-27/25", "36/25", "12/5"), (0, "1232/625", "1024/625", "-12/125")),
                    dqv((0, "12/25", "-16/25", "3/5"), (0, "-207/625", "-99/625", "12/125"))],
        (2, 1, 0): [dqv((0, "9/5", "144/65", "12/13"), (0, "368/325", "-2812/4225", "-516/845")),
                    dqv((0, "-32/25", "138/325", "96/65"),
                        (0, "9741/8125", "192656/105625", "10872/21125")),
                    dqv((0, "12/25", "-16/25", "3/5"), (0, "-207/625", "-99/625", "12/125"))],
        (0, 1, 2): list(TV6_FACTORS),
    }
    facts = factor.all_factorizations(tv6)
    for order, hs in orders.items():
        assert np.allclose(factor.factorize(tv6, list(order)), np.stack(hs), atol=1e-12)
        j = [tuple(o) for o in facts.norm_order.tolist()].index(order)
        assert np.allclose(facts.factors[j], np.stack(hs), atol=1e-12)


def test_tv7_nonzero_scalar_parts():
    hs = np.stack([E[0] + E[1], 2 * E[2] + E[5], -E[0] + 3 * E[3] + E[5] + E[6]])
    c = poly.from_factors(hs)
    quads, code = factor.norm_quadratics_batch(c)
    assert code == 0
    # canonical labels sort by m0: t^2-2t+2 (A), t^2+4 (B), t^2+2t+10 (C)
    assert np.allclose(quads, [[2, -2], [4, 0], [10, 2]])
    got = factor.factorize(c, [2, 1, 0])
    want = np.stack([
        dqv((-1, "21/11", "18/11", "18/11"), (0, "576/605", "-32/121", "-512/605")),
        dqv((0, "-8/33", "34/33", "56/33"), (0, "11393/5445", "772/1089", "-716/5445")),
        dqv((1, "-2/3", "-2/3", "-1/3"), (0, "-47/45", "5/9", "44/45")),
    ])
    assert np.allclose(got, want, atol=1e-12)


@pytest.mark.parametrize("n", [2, 3, 4])
def test_hss_any_degree_and_order(n):
    rng = np.random.default_rng(n)
    c = poly.from_factors(random_rotation_factors(rng, n))
    for order in (list(range(n)), list(range(n))[::-1]):
        h = factor.factorize(c, order)
        assert np.abs(poly.from_factors(h) - c).max() <= 1e-9 * np.abs(c).max()
        quads, _ = factor.norm_quadratics_batch(c)
        for i, lab in enumerate(order):  # factor i has the requested norm quadratic
            assert np.allclose(poly.norm_poly(poly.linear(h[i]))[:2], quads[lab], atol=1e-8)


@settings(max_examples=40, deadline=None)
@given(seeds)
def test_six_factorizations_properties(seed):
    rng = np.random.default_rng(seed)
    c = random_cubic(rng)
    facts = factor.all_factorizations(c)
    prods = poly.from_factors(facts.factors)
    assert np.abs(prods - c).max() <= 1e-9 * np.abs(c).max() * 10
    # six distinct factorizations
    flat = facts.factors.reshape(6, -1)
    dists = np.linalg.norm(flat[:, None] - flat[None], axis=-1) + np.eye(6)
    assert dists.min() > 1e-6
    # flip involution on every neighbouring pair
    for j in range(6):
        for pos in (0, 1):
            f = facts.factors[j]
            k1, k2 = factor.bennett_flip(f[pos], f[pos + 1])
            back = factor.bennett_flip(k1, k2)
            assert np.allclose(np.stack(back), f[pos:pos + 2], atol=1e-8)


@settings(max_examples=20, deadline=None)
@given(seeds)
def test_refinement_restores_perturbed_factors(seed):
    """Newton refinement returns to the factorization from 1e-7 away (each of the six)."""
    rng = np.random.default_rng(seed)
    h = random_rotation_factors(rng)
    c = poly.from_factors(h)
    six = factor.all_factorizations_batch(c).factors
    noisy = factor.clean_factor(six + 1e-7 * rng.standard_normal(six.shape))
    assert factor.product_residual(noisy, c).min() > 1e-9
    fixed = factor.refine_cubic_factors(noisy, c)
    assert factor.product_residual(fixed, c).max() < 1e-12
    assert np.abs(fixed - six).max() < 1e-9 * (1 + np.abs(six).max())


def test_near_singular_motion_factors_multiply_back():
    """Random design 2006 passes within 1e-21 of a singular pose: plain float64 HSS factors
    missed the motion by 2.6e-3 at positions x 1e8; refined (or high-precision) ones do not."""
    import paraloop_core as pl
    from tests.independent.generic_designs import random_design

    for scale in (1.0, 1e8):
        sol = pl.solve(pl.design_from_dict(random_design(2006, scale)), realize=False)
        assert factor.product_residual(sol.factorizations.factors, sol.monic).max() < 1e-8


def test_batched_equals_per_element():
    rng = np.random.default_rng(11)
    cs = random_cubic(rng, (5,))
    batch = factor.all_factorizations_batch(cs)
    for k in range(5):
        single = factor.all_factorizations(cs[k])
        assert np.allclose(batch.factors[k], single.factors)


def test_non_generic_real_root():
    # a translational factor t - eps i/2 has norm t^2 (real double root)
    h = np.stack([E[1], E[5], 3 * E[3] + E[6]])
    with pytest.raises(NonGenericMotionError, match="real root") as info:
        factor.all_factorizations(poly.from_factors(h))
    assert info.value.reason == "real-root"


def test_non_generic_repeated_factor():
    h = np.stack([E[1], E[2] + 2 * E[7], E[3] + E[5]])  # all norms t^2 + 1
    with pytest.raises(NonGenericMotionError, match="repeated") as info:
        factor.all_factorizations(poly.from_factors(h))
    assert info.value.reason == "repeated-factor"


def test_non_generic_singular_remainder():
    # primal part with a real quadratic factor: (t^2 + 1) (t - j) with a dual part
    c = poly.mul(poly.linear(E[1]), poly.linear(-E[1]))  # (t - i)(t + i) = t^2 + 1
    c = poly.mul(c, poly.linear(2 * E[2] + E[7]))
    with pytest.raises(NonGenericMotionError) as info:
        factor.factorize(c)
    assert info.value.reason in ("singular-remainder", "repeated-factor")


def test_not_a_motion_polynomial():
    c = poly.from_factors(TV6_FACTORS)
    c[0, 4] += 1.0  # breaks the Study condition
    with pytest.raises(NonGenericMotionError, match="Study") as info:
        factor.all_factorizations(c)
    assert info.value.reason == "not-motion"


@pytest.mark.parametrize("unit", [1e-4, 1e4])
def test_unit_of_t_changes_no_answer(unit):
    """Roots at |t| ~ 1e4 give a monic cubic with coefficients ~1e12 (seed 536 of the random
    designs was refused as 'leading coefficient zero'): a change of t's unit is no degeneracy."""
    h = random_rotation_factors(np.random.default_rng(53), 3)
    c = poly.from_factors(h)
    scaled = poly.reparametrize(c, unit, 0.0) / unit**3  # C(unit s) / unit^3: monic in s
    f = factor.all_factorizations(scaled)
    err = np.abs(poly.from_factors(f.factors) - scaled).max() / np.abs(scaled).max()
    assert err < 1e-9
