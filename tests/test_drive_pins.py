"""Drive plan numbers pinned to the scalar TOPP implementation (tests/independent/drive_pins.py):
the array version must give the same schedules, limits and messages to 1e-9 relative."""

from __future__ import annotations

import functools
import json
import re

import numpy as np
import pytest

from tests.independent import drive_pins

RTOL = 1e-9
PINS = json.loads(drive_pins.PINS.read_text())
_NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[+-]?\d+)?")


def _close(got, want, path: str, scale: float | None = None) -> None:
    """Recursive comparison: floats to RTOL relative (of the array's largest entry for arrays),
    numbers inside strings likewise, everything else exactly."""
    if isinstance(want, dict):
        assert isinstance(got, dict) and got.keys() == want.keys(), path
        for k in want:
            _close(got[k], want[k], f"{path}.{k}")
    elif isinstance(want, list):
        assert isinstance(got, list) and len(got) == len(want), path
        big = max([abs(w) for w in _leaves(want)] + [scale or 0.0])  # rows: the array's
        for k, (g, w) in enumerate(zip(got, want, strict=True)):
            _close(g, w, f"{path}[{k}]", big)
    elif isinstance(want, str):
        assert isinstance(got, str), path
        assert _NUMBER.sub("#", got) == _NUMBER.sub("#", want), (path, got, want)
        for g, w in zip(_NUMBER.findall(got), _NUMBER.findall(want), strict=True):
            # messages print 3 - 9 significant digits: the last printed digit may differ
            assert float(g) == pytest.approx(float(w), rel=1e-5), (path, got, want)
    elif isinstance(want, float):
        assert isinstance(got, (int, float)), path
        tol = RTOL * max(abs(want), scale or 0.0)
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
def test_drive_plan_matches_the_pinned_scalar_numbers(case, monkeypatch):
    want = PINS[case]
    name = want["design"]
    monkeypatch.setattr(drive_pins, "loops_of", _loops)
    got = json.loads(json.dumps(drive_pins._round(
        drive_pins.pin(name, want["loop"], want["settings"]))))
    _close(got, want, f"case {case} ({name}, loop {want['loop']}, {want['settings']})")


def test_the_pins_cover_schedules_chosen_limits_and_refusals():
    plans = [p["plan"] for p in PINS]
    assert len(PINS) >= 60
    assert sum("achieved_speed_ratio" in p["schedule"] for p in plans) >= 40
    assert sum("error" in p["schedule"] for p in plans) >= 10
    assert {p["limits"]["chosen_by"]["max_accel_rad_s2"] for p in plans} == {"user", "program"}
    assert any(p["tight"] is not None for p in PINS)
