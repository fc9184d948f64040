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
from independent.dense_check import check_result
from independent.generic_designs import random_design

import paraloop_core as pl
from paraloop_core import printed
from paraloop_core.fabrication import choice, printable
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
    index, score = roomy.screen(draws)
    tau, polys = draws.tau[index], draws.polys[index]
    assert 0 < len(tau) <= roomy.EXACT and np.all(np.diff(score) <= 0) and np.all(score > 0)
    assert np.all(tau[:, 2] == 0)  # the held vertex is not shifted
    exact = roomy.exact_clearance(lp, polys)
    sampled = roomy.sampled_clearance(lp, polys)
    assert np.all(exact <= sampled * (1 + 1e-9) + 1e-12)  # samples bound the minimum above
    extent = np.ptp(polys, axis=1).max(axis=1)
    assert np.allclose(exact / extent, score, rtol=1e-9, atol=1e-12)


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
    monkeypatch.setattr(printed, "_roomy_candidates", lambda sol: iter(
        [choice.Candidate("roomy", 0, lambda: (None, None))]))
    cands = printed.candidates(sol, printable.Options().printer)
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
