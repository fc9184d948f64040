"""Beam estimates of the printed links (:mod:`fabrication.stiffness`): the hexagon's section
against a numerical integration, the sag and torque formulas against a numerical beam and
MAKER.md's round-bar figures, the required gaps, the radius a deflection needs."""

from __future__ import annotations

import fab_fixtures as F
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import solve_banded

from paraloop_core.fabrication import parts, stiffness


@pytest.mark.parametrize("r", [1.0, 4.5, 8.0])
def test_hexagon_area_and_second_moment(r):
    """A regular hexagonal prism of corner radius r (the parts' bar, h long): trimesh's mass
    properties give the section's area (volume / h) and its second moments (from the prism's
    inertia tensor at unit density, ``I_xx = h I_x + A h^3 / 12``), about axes turned every
    which way in the section (a regular hexagon's are all equal)."""
    h = 10.0
    bar = F.mesh_of(parts.hex_bar(np.zeros(3), np.array([0.0, 0.0, h]), r, [1.0, 0, 0]))
    area = bar.volume / h
    assert area == pytest.approx(stiffness.hex_area(r), rel=1e-5)
    tensor = bar.moment_inertia  # about the centre of mass, density 1
    for a in np.radians([0.0, 13.0, 30.0, 71.0]):
        n = np.array([np.cos(a), np.sin(a), 0.0])
        i_axis = n @ tensor @ n  # the prism about an axis along n through its centre
        section = (i_axis - area * h**3 / 12.0) / h
        assert section == pytest.approx(stiffness.hex_inertia(r), rel=1e-5)
    # and a plain Monte-Carlo integral over the section, no meshes at all
    rng = np.random.default_rng(0)
    xy = rng.uniform(-r, r, (400_000, 2))
    ang = np.arctan2(xy[:, 1], xy[:, 0])
    # inside the hexagon with corners at 0, 60, ... deg: distance to the nearest side's line
    side = np.pi / 6 + np.pi / 3 * np.floor(ang / (np.pi / 3))
    normal = np.stack([np.cos(side), np.sin(side)], 1)
    inside = np.einsum("nk,nk->n", xy, normal) <= r * np.sqrt(3) / 2
    box = (2 * r) ** 2
    assert inside.mean() * box == pytest.approx(stiffness.hex_area(r), rel=0.01)
    i_mc = np.mean(np.where(inside, xy[:, 1] ** 2, 0.0)) * box
    assert i_mc == pytest.approx(stiffness.hex_inertia(r), rel=0.02)


def _beam_midspan(moment, length: float, ei: float, n: int = 4001) -> float:
    """Mid-span deflection of a simply supported beam under the bending moment ``moment(x)``
    (N mm, sagging positive): ``EI y'' = M`` (y up), ``y(0) = y(L) = 0``, by finite
    differences; the deflection is ``-y(L / 2)``."""
    x = np.linspace(0.0, length, n)
    h = x[1] - x[0]
    bands = np.array([np.ones(n - 2), np.full(n - 2, -2.0), np.ones(n - 2)]) / h**2
    y = solve_banded((1, 1), bands, moment(x[1:-1]) / ei)
    return float(-y[(n - 2) // 2])


def test_sag_and_torque_against_a_numerical_beam():
    length, r, e, rho, tau = 150.0, 4.0, 2.3, 1.24, 0.05
    d = stiffness.deflections(np.full(6, length), np.full(6, r), np.full(6, 1.0), e, rho, tau)
    ei = e * 1e3 * stiffness.hex_inertia(r)
    q = rho * 1e-6 * stiffness.G * stiffness.hex_area(r)  # N/mm
    sag = _beam_midspan(lambda x: q * x * (length - x) / 2.0, length, ei)
    bend = _beam_midspan(lambda x: tau * 1e3 + 0 * x, length, ei)  # end moments
    assert d.sag == pytest.approx(np.full(6, sag), rel=1e-4)
    assert d.torque == pytest.approx(np.full(6, bend), rel=1e-4)
    assert d.total == pytest.approx(d.sag + d.torque)
    # a bar across gravity at sin 0.5 sags half as much; a vertical one not at all
    half = stiffness.deflections([length, length], [r, r], [0.5, 0.0], e, rho, 0.0)
    assert half.sag == pytest.approx([sag / 2, 0.0], rel=1e-4, abs=1e-15)


def test_sag_matches_maker_round_bar_figures():
    """MAKER.md: a round PLA bar, simply supported, sags ``0.21 rho g L^4 / (E d^2)``:
    0.15 mm at L = 170 mm, d = 2 mm and 0.01 mm at d = 8 mm (E = 3.5 GPa, its upper figure).
    A hexagon of corner radius ``d sqrt(0.3)`` has the round bar's area per second moment
    (``16 / d^2``), so the same sag."""
    for d_mm, figure in ((2.0, 0.15), (8.0, 0.01)):
        r = d_mm * np.sqrt(0.3)
        assert stiffness.hex_area(r) / stiffness.hex_inertia(r) == pytest.approx(16 / d_mm**2)
        sag = stiffness.deflections([170.0], [r], [1.0], 3.5, 1.24, 0.0).sag[0]
        assert sag == pytest.approx(figure, abs=0.005)
        rough = 0.21 * 1240 * 9.81 * 0.170**4 / (3.5e9 * (d_mm * 1e-3) ** 2) * 1e3
        assert sag == pytest.approx(rough, rel=0.01)  # 5/24 = 0.208 is MAKER's 0.21


@settings(max_examples=50, deadline=None)
@given(st.floats(0.05, 2.0), st.floats(20.0, 300.0), st.floats(1.0, 4.0), st.floats(0.0, 2.0))
def test_radius_for_meets_the_deflection(delta, length, e, tau):
    r = stiffness.radius_for(delta, np.full(6, length), e, 1.24, tau)
    d = stiffness.deflections(np.full(6, length), r, np.ones(6), e, 1.24, tau)
    assert d.total == pytest.approx(np.full(6, delta), rel=1e-9)
    thinner = stiffness.deflections(np.full(6, length), r * 0.99, np.ones(6), e, 1.24, tau)
    assert np.all(thinner.total > delta)


def test_required_gaps():
    d = np.array([0.1, 0.0, 0.3, 0.05, 0.2, 0.0])
    g = stiffness.required_gaps(d)
    assert g.shape == (6, 6) and np.allclose(g, g.T)
    for a in range(6):
        for b in range(6):
            if b in ((a + 1) % 6, (a - 1) % 6):  # one joint: the least gap
                assert g[a, b] == stiffness.MIN_GAP_MM
            elif a != b:
                assert g[a, b] == pytest.approx(max(1.0, 3.0 * (d[a] + d[b])))
    assert g[0, 2] == pytest.approx(1.2) and g[2, 4] == pytest.approx(1.5)
    assert g[1, 3] == pytest.approx(1.0)  # 3 x 0.05 is under the least gap


def test_rod_deflection_is_a_cantilever_under_an_end_moment():
    # M L^2 / (2 E I): 1 N at 100 mm on a 6 mm steel rod 80 mm long
    ei = 200e3 * np.pi * 6.0**4 / 64
    assert stiffness.rod_deflection(80.0, 6.0, 200.0, 1.0, 100.0) == pytest.approx(
        100.0 * 80.0**2 / (2 * ei))


def test_across_gravity_of_the_printed_loop():
    """|sin| of each bar's angle to the vertical over the cycle: in [0, 1]; the resting
    link's bar does not move, so its value is the home one; the others' reach their largest
    value at some sample of a dense independent sampling."""
    asm = F.printed().assembly
    g, up = asm.base.link, asm.base.up
    across = stiffness.across_gravity(asm.joint_factors, list(asm.bars), g, up)
    assert np.all((across >= 0) & (across <= 1))
    bar = asm.bars[g][0]
    d = (bar[1] - bar[0]) / np.linalg.norm(bar[1] - bar[0])
    assert across[g] == pytest.approx(np.sqrt(1 - (d @ up) ** 2))
    u = np.linspace(0.0, 1.0, 2001)
    rel = F.relative_poses(asm.joint_factors, asm.scale, g, u)
    for i in range(6):
        b = asm.bars[i][0]
        v = np.einsum("tij,j->ti", rel[:, i, :3, :3], b[1] - b[0])
        sin = np.sqrt(1 - (v @ up / np.linalg.norm(v, axis=1)) ** 2)
        assert sin.max() == pytest.approx(across[i], abs=2e-3)
