"""Roomy realizations for printing (``paraloop_core/realization/roomy.py``).

The screen only orders candidates; the certificate is the paper search's. So: the exact
clearance never exceeds the sampled one, held vertices stay put, a roomy realization's
certificate survives the independent dense referee, and it leaves far more room per extent
than the paper's shortest polyline on designs whose shortest polylines pass close.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from independent.dense_check import check_result
from independent.generic_designs import random_design
from independent.segdist import segment_distance

import paraloop_core as pl
from paraloop_core import printed
from paraloop_core.fabrication import choice, printable
from paraloop_core.printed import ROOMY_PIN
from paraloop_core.realization import realize, roomy


@pytest.fixture(scope="module")
def close_design() -> pl.Solution:
    """A generic design whose own realization leaves little room (seed 62014: the paper's
    thin polylines of its loop pass within 1.5 % of the extent)."""
    return pl.solve(pl.design_from_dict(random_design(62014, 1.0)))


def test_screen_orders_by_exact_clearance_below_the_samples(close_design):
    jf, unit = close_design.search_factors(1)
    draws = roomy.draw(jf, {2: 0.0}, unit)
    lp = draws.lp
    index, score, thin = roomy.screen(draws, ROOMY_PIN)
    tau, polys = draws.tau[index], draws.polys[index]
    assert 0 < len(tau) <= roomy.EXACT and np.all(np.diff(score) <= 0) and np.all(score > 0)
    assert np.all(score <= thin)  # the thin clearance, or less where the joints' bars pass
    assert np.all(tau[:, 2] == 0)  # the held vertex is not shifted
    exact = roomy.exact_clearance(lp, polys)
    sampled = roomy.sampled_clearance(lp, polys)
    assert np.all(exact <= sampled * (1 + 1e-9) + 1e-12)  # samples bound the minimum above
    extent = np.ptp(polys, axis=1).max(axis=1)
    assert np.allclose(exact / extent, thin, rtol=1e-9, atol=1e-12)
    joints = roomy.joint_clearance(lp.u, polys, ROOMY_PIN * extent)
    assert np.allclose(np.minimum(exact, joints) / extent, score, rtol=1e-9, atol=1e-12)


def test_draws_round_the_design_polyline_find_room_the_wide_draws_miss():
    """Random 62219: on the loop the design realized, none of the wide draws the screen
    checks is collision-free; drawn close round the design's own free polyline, some are,
    and the export tries them after the wide draws of every loop."""
    sol = pl.solve(pl.design_from_dict(random_design(62219, 1.0)))
    loop, p = sol.design.loop, sol.design.realization.p
    assert len(roomy.screen(printed._draws(sol, loop), ROOMY_PIN)[0]) == 0
    close = printed._draws(sol, loop, close=True)
    center = np.rint(np.asarray(sol.realization.shifts) * roomy.FINE_P / p).astype(int)
    assert len(close.tau) == roomy.LOCAL_DRAWS * len(roomy.LOCAL_SCALES)
    assert np.all(np.abs(close.tau - center) <= max(roomy.LOCAL_SCALES) * roomy.FINE_P + 0.5)
    index, score, thin = roomy.screen(close, ROOMY_PIN)
    assert len(index) > 0 and np.all(score > 0)
    exact = roomy.exact_clearance(close.lp, close.polys[index]) / close.extent[index]
    assert np.allclose(exact, thin, rtol=1e-9)
    labels = [c.label for c in printed._roomy_candidates(sol, [])]
    assert len(labels) == len(sol.loops) + 1 and "near the design's" in labels[-1]
    assert labels[-1].startswith(f"loop {loop},")


def _joint_clearance_dense(u, v, pin, turns=720):
    """The two bars at each joint of one thin polyline ``v`` ``(6, 3)`` split by ``pin`` (the
    bar leaning further along the axis at its upper end), the second turned about the axis
    at ``turns`` angles: their least distance (independent segment distances)."""
    best = np.inf
    for i in range(6):
        bar_in, bar_out = v[i - 1] - v[i], v[(i + 1) % 6] - v[i]
        lean_in = bar_in @ u[i] / np.linalg.norm(bar_in)
        lean_out = bar_out @ u[i] / np.linalg.norm(bar_out)
        half = pin / 2 if lean_out >= lean_in else -pin / 2
        a0, b0 = v[i] - half * u[i], v[i] + half * u[i]
        for t in np.linspace(0, 2 * np.pi, turns, endpoint=False):
            k = np.array([[0, -u[i, 2], u[i, 1]], [u[i, 2], 0, -u[i, 0]],
                          [-u[i, 1], u[i, 0], 0]])
            rot = np.eye(3) + np.sin(t) * k + (1 - np.cos(t)) * k @ k
            best = min(best, segment_distance(a0, a0 + bar_in, b0, b0 + rot @ bar_out))
    return best


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_joint_clearance_samples_the_turn_of_each_joint(seed):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(1, 6, 3))
    u = rng.normal(size=(6, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    pin = rng.uniform(0.05, 0.5)
    got = roomy.joint_clearance(u, v, np.array([pin]))[0]
    dense = _joint_clearance_dense(u, v[0], pin)
    # sampled angles: an upper bound of the dense minimum, within the far end's move over
    # half a sampling step (segment distances are 1-Lipschitz in the ends)
    step = np.pi / roomy.TURN_SAMPLES
    reach = np.linalg.norm(np.roll(v[0], -1, axis=0) - v[0], axis=1).max()
    assert dense - 1e-12 <= got <= dense + reach * step + 1e-12


def test_bars_square_to_their_axes_keep_the_pin_apart():
    ring = np.array([[np.cos(a), np.sin(a), 0.0] for a in np.arange(6) * np.pi / 3])
    u = np.tile([0.0, 0.0, 1.0], (6, 1))  # every axis square to the plane of the bars
    assert roomy.joint_clearance(u, ring[None], np.array([0.2]))[0] == pytest.approx(0.2)


def test_roomy_certificates_survive_the_referee_and_make_it_printable(close_design):
    """Every roomy realization the export would try (loops by promise) is certified (the
    dense referee agrees with every pair) until one sizes for print with real joints, which
    the design's own realization does not."""
    sol = close_design
    with pytest.raises(pl.FabricationError, match="do not fit in the room"):
        choice._plan(sol.realization, printable.Options())
    sized = None
    for loop in sorted(range(len(sol.loops)), key=lambda i: -roomy.draw(*_factors(sol, i)).promise):
        try:
            roomy_sol = printed.roomy_variant(sol, loop, printed.ROOMY_PIN)
        except pl.RealizationError:
            continue
        rep = check_result(pl.result_to_dict(roomy_sol))
        assert rep["status"] == "checked" and rep["disagreements"] == [], loop
        try:
            sized = choice._plan(roomy_sol.realization, printable.Options())
            break
        except pl.FabricationError:
            continue
    assert sized is not None and sized.radii.min() * np.sqrt(3) >= 6.0


def test_run_hint_over_all_offsets_finds_the_search_answer():
    """``run_hint(shifts, None)`` certifies what :meth:`Search.run` found for those shifts."""
    sol = pl.solve(pl.load_design("assets/designs/tv8.json"))
    real = sol.realization
    jf, unit = sol.search_factors(sol.design.loop)
    rs = sol.design.realization
    again = realize.Search(jf, dict(rs.fixed), unit).run_hint(
        real.shifts, None, p=rs.p, rho=real.radius, d=real.separation, d_fraction=0.0,
        rho_fraction=0.0, max_k=rs.max_k)
    assert again is not None
    assert np.array_equal(again.offsets, real.offsets)
    assert np.allclose(again.points, real.points, rtol=1e-9, atol=1e-12 * real.length)


def _factors(sol: pl.Solution, loop: int) -> tuple:
    jf, unit = sol.search_factors(loop)
    return jf, dict(sol.design.realization.fixed), unit


@pytest.mark.parametrize("first_found", [True, False])
def test_roomy_candidates_follow_a_first_search_that_found_none(first_found, monkeypatch):
    """The design's loop is tried twice before the roomy realizations, unless its first
    search found nothing (the second repeats it with thinner bars): then they come next."""
    from types import SimpleNamespace

    from paraloop_core.errors import RealizationError

    tv8 = Path(__file__).resolve().parents[1] / "assets" / "designs" / "tv8.json"
    sol = pl.solve(pl.load_design(tv8), realize=False)

    def variant(*args, **kwargs):
        if not first_found:
            raise RealizationError("no realization in the budget", "not-found")
        return SimpleNamespace(realization=None, end_effector=None)

    monkeypatch.setattr(printed, "realize_variant", variant)
    monkeypatch.setattr(printed, "_roomy_candidates", lambda sol, made: iter(
        [choice.Candidate("roomy", 0, lambda: (None, None))]))
    made: list = []
    cands = printed.candidates(sol, printable.Options().printer, made)
    first = next(cands)
    if first_found:
        first.make()
    else:
        with pytest.raises(RealizationError):
            first.make()
    labels = [next(cands).label for _ in range(3)]
    if first_found:
        assert "bars 0.35 d" in labels[0] and labels[1] == "roomy"
    else:
        assert labels[0] == "roomy" and "bars 0.35 d" in labels[1]
    assert labels.count("roomy") == 1
