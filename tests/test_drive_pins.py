"""Drive plan numbers pinned to the scalar TOPP implementation (tests/independent/drive_pins.py):
the array version must give the same schedules, limits and messages to 1e-9 relative.

Accelerations are the slopes of ``x = omega^2`` over each step; over the narrowest steps
(down to 1e-12 rad) the rounding of x alone moves them by up to 1e-4 in either version, so
the accelerations and the achieved maxima that include those steps hold to :data:`NOISY`;
``achieved_accel_wide`` (steps wider than ``drive_pins.WIDE``) holds to RTOL."""

from __future__ import annotations

import functools
import json
import re

import numpy as np
import pytest

from tests.independent import drive_pins

RTOL = 1e-9
NOISY = 1e-3  # relative, for the keys below (see the module doc)
NOISY_KEYS = ("achieved_accel_rad_s2", "achieved_accel", "acceleration", "acceleration_abs_sum")
PINS = json.loads(drive_pins.PINS.read_text())
_NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[+-]?\d+)?")


def _close(got, want, path: str, scale: float | None = None, rtol: float = RTOL) -> None:
    """Recursive comparison: floats to ``rtol`` relative (of the array's largest entry for
    arrays), numbers inside strings to 1e-5, everything else exactly."""
    if isinstance(want, dict):
        assert isinstance(got, dict) and got.keys() == want.keys(), path
        for k in want:
            _close(got[k], want[k], f"{path}.{k}", None, NOISY if k in NOISY_KEYS else rtol)
    elif isinstance(want, list):
        assert isinstance(got, list) and len(got) == len(want), path
        big = max([abs(w) for w in _leaves(want)] + [scale or 0.0])  # rows: the array's
        for k, (g, w) in enumerate(zip(got, want, strict=True)):
            _close(g, w, f"{path}[{k}]", big, rtol)
    elif isinstance(want, str):
        assert isinstance(got, str), path
        assert _NUMBER.sub("#", got) == _NUMBER.sub("#", want), (path, got, want)
        for g, w in zip(_NUMBER.findall(got), _NUMBER.findall(want), strict=True):
            # messages print 3 - 9 significant digits: the last printed digit may differ
            assert float(g) == pytest.approx(float(w), rel=1e-5), (path, got, want)
    elif isinstance(want, float):
        assert isinstance(got, (int, float)), path
        tol = rtol * max(abs(want), scale or 0.0)
        assert abs(got - want) <= tol or (np.isinf(want) and got == want), (path, got, want)
    else:
        assert got == want, (path, got, want)


def _leaves(x):
    if isinstance(x, list):
        for v in x:
            yield from _leaves(v)
    elif isinstance(x, float) and np.isfinite(x):
        yield x


_loops = functools.cache(drive_pins.loops_of)  # one solve per design for all its cases


@pytest.mark.parametrize("case", range(len(PINS)))
def test_drive_plan_matches_the_pinned_scalar_numbers(case):
    want = PINS[case]
    name, jf = want["design"], np.array(want["joint_factors"])
    got = json.loads(json.dumps(drive_pins._round(
        drive_pins.pin(name, want["loop"], want["settings"], jf))))
    _close(got, want, f"case {case} ({name}, loop {want['loop']}, {want['settings']})")


def test_the_pins_cover_schedules_chosen_limits_and_refusals():
    plans = [p["plan"] for p in PINS]
    assert len(PINS) >= 60
    assert sum("achieved_speed_ratio" in p["schedule"] for p in plans) >= 40
    assert sum("error" in p["schedule"] for p in plans) >= 10
    assert {p["limits"]["chosen_by"]["max_accel_rad_s2"] for p in plans} == {"user", "program"}
    assert any(p["tight"] is not None for p in PINS)
    # the noisy keys agree far better than NOISY where no step is narrow
    wide = [p["schedule"] for p in PINS if "schedule" in p]
    assert sum(np.allclose(s["achieved_accel"], s["achieved_accel_wide"], rtol=1e-12)
               for s in wide) >= len(wide) // 2


@pytest.mark.parametrize("name", [*drive_pins.BUNDLED[:3], *drive_pins.SEEDS[:4]])
def test_fastest_equals_the_scalar_recursion(name):
    """The array TOPP passes against the scalar loops, node by node (relative to each node's
    own x, which spans up to 12 orders of magnitude), coarse and full grids, slack and tight
    limits."""
    from paraloop_core.linkage import drive, schedule

    for jf in _loops(name)[::4]:
        _, a, b = drive.norm_roots(jf)
        for m, samples in ((0, 32), (3, 256)):
            gr = schedule.schedule_grid(a, b, m, samples)
            g = gr.g[: len(gr.nodes)]
            r0 = float(schedule.step_times(gr.nodes, schedule.speed_caps(g, 2 * np.pi)).sum())
            for ratio, accel in ((1.05, 1e3), (1.5, 30.0), (4.0, 1.0), (50.0, 0.1)):
                cap = schedule.speed_caps(g, ratio * r0 * 2 * np.pi)
                x, time = schedule.fastest(gr, cap, accel)
                ref, ref_time = drive_pins.scalar_fastest(gr, cap, accel)
                np.testing.assert_allclose(x, ref, rtol=1e-10, atol=0)
                assert time == pytest.approx(ref_time, rel=1e-12)


def test_fastest_falls_back_to_the_scalar_recursion(monkeypatch):
    """With no policy iteration to spare the scalar recursion inside the array pass takes over
    (the fallback for pieces that keep changing or sums that lose digits): same numbers."""
    from paraloop_core.linkage import drive, schedule

    _, a, b = drive.norm_roots(_loops("tv8")[0])
    gr = schedule.schedule_grid(a, b, 1, 64)
    cap = schedule.speed_caps(gr.g[: len(gr.nodes)], 3.0 * 2 * np.pi)
    want = schedule.fastest(gr, cap, 20.0)
    monkeypatch.setattr(schedule, "_POLICY", 0)
    got = schedule.fastest(gr, cap, 20.0)
    np.testing.assert_allclose(got[0], want[0], rtol=1e-10)
    ref = drive_pins.scalar_fastest(gr, cap, 20.0)
    np.testing.assert_allclose(got[0], ref[0], rtol=1e-13)
