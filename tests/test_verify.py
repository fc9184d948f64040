"""Soundness of the branch-and-bound pair minima (:mod:`paraloop_core.realization.verify`)
against an independent dense computation (own point action, own segment distance)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from scipy.optimize import minimize_scalar

from paraloop_core.algebra import factor, poly
from paraloop_core.linkage import loops
from paraloop_core.realization import clearance, realize, verify
from paraloop_core.validation import table1
from tests.conftest import random_rotation_factors, seeds

DENSE_U = np.linspace(0.0, 1.0, 20_000, endpoint=False)  # u = 0 is t = inf


def _qmul(a, b):
    a0, av = a[..., :1], a[..., 1:]
    b0, bv = b[..., :1], b[..., 1:]
    return np.concatenate([a0 * b0 - np.sum(av * bv, -1, keepdims=True),
                           a0 * bv + b0 * av + np.cross(av, bv)], axis=-1)


def _conj(q):
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def _pose(c, th):
    """``cos(th)^k C(tan th)`` ``(U, 8)``: the pose at ``t = tan th``, finite at inf."""
    th = np.atleast_1d(np.asarray(th, float))
    k = len(c) - 1
    s, co = np.sin(th)[:, None], np.cos(th)[:, None]
    return sum(s**m * co ** (k - m) * c[m] for m in range(k + 1))


def _theta(t):
    return -np.pi / 2 if np.isinf(t) else float(np.arctan(t))


def _act(q, x):
    """Point action ``(P x P~ + 2 D P~) / |P|^2`` of poses ``(U, 8)`` on points ``(3,)``."""
    p, d = q[:, :4], q[:, 4:]
    xq = np.concatenate([[0.0], x])
    num = _qmul(_qmul(p, np.broadcast_to(xq, p.shape)), _conj(p)) + 2.0 * _qmul(d, _conj(p))
    return num[:, 1:] / np.sum(p * p, -1)[:, None]


def _point_seg(x, q0, q1):
    """Distance ``(...)`` of points ``x`` to segments ``[q0, q1]`` (exact clamped projection)."""
    e = q1 - q0
    ee = np.maximum(np.sum(e * e, -1), 1e-300)
    w = np.clip(np.sum((x - q0) * e, -1) / ee, 0.0, 1.0)
    return np.linalg.norm(x - q0 - w[..., None] * e, axis=-1)


def _seg_dist(p0, p1, q0, q1):
    """Segment distance: the minimum is either interior to both segments (closest points of the
    two lines, if both parameters lie in [0, 1]) or has an endpoint on one of them."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, b = (np.sum(x * y, -1) for x, y in ((d1, d1), (d2, d2), (d1, d2)))
    c, f = np.sum(d1 * r, -1), np.sum(d2 * r, -1)
    den = a * e - b * b
    ok = den > 1e-12 * a * e
    s = (b * f - c * e) / np.where(ok, den, 1.0)
    u = (a * f - b * c) / np.where(ok, den, 1.0)
    inner = ok & (s >= 0) & (s <= 1) & (u >= 0) & (u <= 1)
    diff = r + s[..., None] * d1 - u[..., None] * d2
    best = np.where(inner, np.linalg.norm(diff, axis=-1), np.inf)
    for x, (y0, y1) in ((p0, (q0, q1)), (p1, (q0, q1)), (q0, (p0, p1)), (q1, (p0, p1))):
        best = np.minimum(best, _point_seg(x, y0, y1))
    return best


def _distance(c, fixed, moving, th):
    q = _pose(c, th)
    return _seg_dist(np.broadcast_to(fixed[0], (len(q), 3)), np.broadcast_to(fixed[1], (len(q), 3)),
                     _act(q, moving[0]), _act(q, moving[1]))


def _dense_min(c, fixed, moving, extra_th=()):
    th = np.sort(np.concatenate([np.pi * (DENSE_U - 0.5), np.asarray(extra_th, float)]))
    vals = _distance(c, fixed, moving, th)
    best = float(vals.min())
    for k in np.argsort(vals)[:4]:
        # between the neighbouring samples, as an offset: Brent's relative tolerance then
        # stays far below the spacing (theta is periodic: pi is the same pose)
        lo = (th[k - 1] - th[k]) if k > 0 else th[-1] - np.pi - th[k]
        hi = (th[k + 1] - th[k]) if k + 1 < len(th) else th[0] + np.pi - th[k]
        res = minimize_scalar(lambda x, k=k: float(_distance(c, fixed, moving, th[k] + x)[0]),
                              bounds=(lo, hi), method="bounded", options={"xatol": 1e-15})
        best = min(best, float(res.fun))
    return best


def _check(jf, fixed, moving, links, tol=1e-6, extra_th=()):
    b = verify.pair_bounds(jf, fixed, moving, links, tol)
    for row in range(len(fixed)):
        c = loops.relative_motion(jf, *links[row])
        scale = 1.0 + np.abs(fixed[row]).max() + np.abs(moving[row]).max()
        dense = _dense_min(c, fixed[row], moving[row], extra_th)
        up, lo = b.upper[row], b.lower[row]
        assert lo <= dense + 1e-9 * scale, (row, lo, dense)
        assert up >= dense - 1e-9 * scale, (row, up, dense)
        assert lo <= up
        if b.cells[row] < verify._MAX_CELLS:
            assert up - lo <= tol + verify.RELATIVE * up + 1e-12 * scale, (row, up, lo)
        t = b.t[row]
        at = _distance(c, fixed[row], moving[row], _theta(t))[0]
        assert at == pytest.approx(up, abs=1e-9 * scale)
    return b


def _random_case(seed, n_pairs):
    rng = np.random.default_rng([seed, 7])
    jf = table1.random_loops(seed, 1)[0, int(rng.integers(2))]
    links = np.array([rng.choice(6, 2, replace=False) for _ in range(n_pairs)])
    fixed = rng.normal(size=(n_pairs, 2, 3)) * rng.uniform(0.2, 2.0)
    moving = rng.normal(size=(n_pairs, 2, 3)) * rng.uniform(0.2, 2.0)
    return jf, fixed, moving, links


def test_random_loops_and_segments():
    jf, fixed, moving, links = _random_case(11, 6)
    _check(jf, fixed, moving, links)


def test_joint_pairs_of_a_polyline():
    jf = table1.random_loops(4, 1)[0, 1]
    pts = np.random.default_rng(4).normal(size=(12, 3))
    pairs = verify.JOINT_PAIRS
    b = verify.polyline_bounds(jf, pts, pairs, 1e-6)
    e1, e2 = pairs[:, 0], pairs[:, 1]
    fixed = np.stack([pts[e1], pts[(e1 + 1) % 12]], axis=1)
    moving = np.stack([pts[e2], pts[(e2 + 1) % 12]], axis=1)
    ref = _check(jf, fixed, moving, pairs[:, 2:])
    np.testing.assert_array_equal(b.upper, ref.upper)
    np.testing.assert_array_equal(b.lower, ref.lower)


def _far_root_loop():
    """A loop whose norm roots are far apart (h0 = -1e3, 0, 1e3): the cycle's slow parts sit
    at |t| ~ 1e3..1e4, i.e. within 1e-3 of u = 0 (t = inf)."""
    h = random_rotation_factors(np.random.default_rng(5), 3)
    h[:, 0] = [-1e3, 0.0, 1.1e3]
    f = factor.all_factorizations(poly.from_factors(h))
    return loops.loop_joint_factors(f.factors)[0]


@pytest.mark.parametrize("t_star", [3e3, -5e3, 2e4])
def test_minimum_near_infinity(t_star):
    jf = _far_root_loop()
    rng = np.random.default_rng(int(abs(t_star)))
    rows = []
    for i, j in [(0, 1), (0, 2), (0, 3), (1, 4)]:
        c = loops.relative_motion(jf, i, j)
        fixed = rng.normal(size=(2, 3))
        # moving segment = fixed one pulled back by R(t*) and nudged: the pair meets near t*
        rows.append(((i, j), fixed, _pulled_back(c, fixed, t_star, rng)))
    links = np.array([r[0] for r in rows])
    b = _check(jf, np.array([r[1] for r in rows]), np.array([r[2] for r in rows]), links)
    assert np.all(b.upper < 0.05)


def _pulled_back(c, fixed, t_star, rng):
    """A moving segment that meets ``fixed`` near ``t_star`` (``fixed`` pulled back, nudged)."""
    inv = _pose(poly.conj(c), _theta(t_star))
    return np.stack([_act(inv, x)[0] for x in fixed]) + 0.01 * rng.normal(size=3)


@pytest.mark.parametrize("width", [1e-3, 1e-6])
def test_fast_turn(width):
    """One joint turns within ``|t - 0.3| ~ width`` (a norm root that close to the real axis):
    the expanded ``|P|^2`` loses all digits there, the factored bound must stay sound and
    tight, and the exact kernel (charts) must find the minimum inside the turn."""
    h = random_rotation_factors(np.random.default_rng(8), 3)
    h[:, 0] = [0.3, -1.0, 2.0]
    h[0, 1:4] *= width / np.linalg.norm(h[0, 1:4])
    h[0, 5:8] *= width / np.linalg.norm(h[0, 5:8])
    jf = loops.loop_joint_factors(factor.all_factorizations(poly.from_factors(h)).factors)[0]
    rng = np.random.default_rng(3)
    rows = []
    for i, j in [(0, 1), (0, 3), (5, 2)]:
        c = loops.relative_motion(jf, i, j)
        fixed = rng.normal(size=(2, 3))
        rows.append(((i, j), fixed, _pulled_back(c, fixed, 0.3 + 0.4 * width, rng)))
    links = np.array([r[0] for r in rows])
    fixed, moving = np.array([r[1] for r in rows]), np.array([r[2] for r in rows])
    extra = np.arctan(0.3 + width * np.linspace(-50.0, 50.0, 20_001))  # resolve the turn
    b = _check(jf, fixed, moving, links, extra_th=extra)
    pm = clearance.PairMotions(jf, [tuple(k) for k in links])
    for row, key in enumerate(links):
        md, n = pm.data([tuple(key)])[0]
        exact, _ = clearance.min_distance_batch(md, np.array([n]), fixed[row:row + 1],
                                                moving[row:row + 1])
        assert b.lower[row] - 1e-9 <= exact[0] <= b.upper[row] + 1e-6 + verify.RELATIVE


@pytest.mark.parametrize("t_star", [3e3, -5e3])
def test_exact_kernel_finds_contacts_far_out(t_star):
    """The exact minimum (search side) against the sound bounds where the roots are far apart."""
    jf = _far_root_loop()
    rng = np.random.default_rng(int(abs(t_star)))
    keys = [(0, 2), (1, 4), (2, 5)]
    pm = clearance.PairMotions(jf, keys)
    for key in keys:
        c = loops.relative_motion(jf, *key)
        fixed = rng.normal(size=(2, 3))
        moving = _pulled_back(c, fixed, t_star, rng)
        b = verify.pair_bounds(jf, fixed[None], moving[None], np.array([key]), 1e-6)
        md, n = pm.data([key])[0]
        exact, _ = clearance.min_distance_batch(md, np.array([n]), fixed[None], moving[None])
        assert b.lower[0] - 1e-9 <= exact[0] <= b.upper[0] + 1e-6 + verify.RELATIVE


@pytest.mark.parametrize("joint", range(6))
def test_flat_minimum_on_a_common_axis(joint):
    jf = table1.random_loops(2, 1)[0, 0]
    p, d = jf[joint, 1:4], jf[joint, 5:8]
    foot = np.cross(p, d) / (p @ p)
    u = p / np.linalg.norm(p)
    fixed = np.array([[foot - u, foot + 0.5 * u]])
    moving = np.array([[foot + 1.0 * u, foot + 2.0 * u]])  # constant distance 0.5
    b = _check(jf, fixed, moving, np.array([[joint, (joint + 1) % 6]]))
    assert b.upper[0] == pytest.approx(0.5, abs=1e-9)
    assert b.lower[0] >= 0.5 - 1e-6 - verify.RELATIVE * 0.5
    assert b.cells[0] < verify._MAX_CELLS


@settings(max_examples=15, deadline=None)
@given(seeds)
def test_property_random_seeds(seed):
    _check(*_random_case(seed, 3))


@pytest.mark.parametrize("seed,kind", [(9, 0), (13, 1)])
def test_realize_certificate_is_sound(seed, kind):
    r = realize.realize(table1.random_loops(seed, 1)[0, kind])
    assert np.all(r.pair_lower >= 2 * r.radius)
    assert np.all(r.pair_lower <= r.pair_distance)
    assert r.certified_clearance <= r.min_clearance
