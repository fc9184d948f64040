"""Where a lifted link's keel may run (:mod:`fabrication.keel`), checked by brute force: the
neighbour's bar turned about the joint's axis, and the keel's deepest section measured."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from paraloop_core.fabrication import keel

BAR = np.array([[0.0, 0, 0], [200.0, 0, 0]])
DOWN = np.array([0.0, 0, -1])  # the keel grows towards -z
RADIUS = 4.0


def _deepest(x: np.ndarray, bottom: float) -> np.ndarray:
    """The keel's box section below the axis at stations ``x``: its outline sampled every
    0.2 mm ``(X, P, 3)``."""
    side = np.cross([1.0, 0, 0], DOWN)
    across = np.linspace(-RADIUS, RADIUS, 41)
    down = np.linspace(0.0, bottom, int(bottom / 0.2) + 2)
    outline = np.concatenate([
        across[:, None] * side + bottom * DOWN,
        np.concatenate([s * RADIUS * side + down[:, None] * DOWN for s in (-1, 1)])])
    return np.array([1.0, 0, 0]) * x[:, None, None] + outline


def _swept_gap(points: np.ndarray, n: keel.Neighbour, turns: int = 360) -> np.ndarray:
    """Least distance ``(X,)`` of each station's points to the neighbour's bar turned about
    the axis through a whole turn, less its radius (brute force over the angle)."""
    w = n.w / np.linalg.norm(n.w)
    out = np.full(points.shape[0], np.inf)
    for phi in np.linspace(0.0, 2 * np.pi, turns, endpoint=False):
        k = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        rot = np.eye(3) + np.sin(phi) * k + (1 - np.cos(phi)) * k @ k
        a, b = (rot @ (p - n.origin) + n.origin for p in n.bar)
        t = np.clip(((points - a) @ (b - a)) / ((b - a) @ (b - a)), 0.0, 1.0)
        d = np.linalg.norm(points - (a + t[..., None] * (b - a)), axis=-1).min(axis=-1)
        out = np.minimum(out, d - n.radius)
    return out


def test_no_neighbour_leaves_the_whole_bar():
    assert keel.span(BAR, RADIUS, DOWN, 5.0, ()) == (0.0, 200.0)
    assert keel.capsule_radius(3.0, 8.0) == pytest.approx(5.0, abs=1e-3)


@settings(max_examples=15, deadline=None)
@given(st.floats(4.0, 14.0), st.floats(8.0, 20.0), st.floats(-0.6, 0.6), st.floats(20.0, 110.0))
def test_the_span_keeps_clear_of_a_swept_neighbour(depth, below, tilt, reach):
    """A neighbour on the axis through ``BAR[0]`` (along the keel's side of it), its bar
    leaving the axis ``below`` mm down and ``tilt`` out of level: inside the span the keel's
    section (``depth`` below the axis) keeps ``CLEAR_MM`` from the bar in any turn of the
    joint, less half the span's spacing of its samples; the station just before the span
    does not (or the span starts at the bar's end)."""
    w = DOWN
    end = np.array([reach, 0.0, -below - tilt * reach])
    n = keel.Neighbour(np.zeros(3), w, np.stack([np.array([0, 0, -below]), end]), 3.0)
    got = keel.span(BAR, RADIUS, DOWN, depth, (n,))
    xs = np.linspace(0.0, 200.0, keel.STATIONS)
    gaps = _swept_gap(_deepest(xs, depth), n)
    if got is None:  # no clear stretch of MIN_SHARE of the bar
        clear = gaps >= keel.CLEAR_MM + 0.02
        assert clear.sum() < keel.MIN_SHARE * keel.STATIONS + 2
        return
    x0, x1 = got
    inside = (xs >= x0) & (xs <= x1)
    assert gaps[inside].min() >= keel.CLEAR_MM - keel.SPACING_MM / 2 - 0.02
    assert x1 - x0 >= keel.MIN_SHARE * 200.0
    if x0 > 0:
        assert gaps[np.flatnonzero(inside)[0] - 1] < keel.CLEAR_MM + 0.02


def test_a_neighbour_along_the_whole_bar_leaves_no_keel():
    n = keel.Neighbour(np.zeros(3), DOWN, np.array([[0, 0, -12.0], [300.0, 0, -12.0]]), 3.0)
    assert keel.span(BAR, RADIUS, DOWN, 9.0, (n,)) is None
    shallow = keel.span(BAR, RADIUS, DOWN, 7.0, (n,))  # 12 - 7 - 3 >= 1.5
    assert shallow == (0.0, 200.0)


@pytest.mark.parametrize("bottom", [6.0, 9.0])
def test_the_span_starts_past_a_level_neighbour(bottom):
    """A level neighbour bar 12 mm down, 60 mm long: the keel's bottom comes within
    CLEAR_MM of its top (9 mm down) only at 9 mm: then it starts past the swept disc's rim,
    where the bottom's distance to the rim clears it."""
    n = keel.Neighbour(np.zeros(3), DOWN, np.array([[0, 0, -12.0], [60.0, 0, -12.0]]), 3.0)
    x0, x1 = keel.span(BAR, RADIUS, DOWN, bottom, (n,))
    assert x1 == 200.0
    assert x0 == 0.0 if bottom == 6.0 else 60.0 < x0 < 66.0
