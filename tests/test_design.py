"""Design format: round trip, examples load, every bad field is named."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest

from paraloop_core import design as dm
from paraloop_core.errors import DesignFileError

ASSETS = Path(__file__).resolve().parents[1] / "assets" / "designs"
TV8 = json.loads((ASSETS / "tv8.json").read_text())


def _rounded(obj):
    """Floats to 12 significant digits (normalizing a unit quaternion again moves the last bit)."""
    if isinstance(obj, float):
        return float(f"{obj:.12g}")
    if isinstance(obj, dict):
        return {k: _rounded(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_rounded(v) for v in obj]
    return obj


@pytest.mark.parametrize("path", sorted(ASSETS.glob("*.json")), ids=lambda p: p.name)
def test_examples_load_and_round_trip(path, tmp_path):
    d = dm.load_design(path)
    out = tmp_path / "d.json"
    dm.save_design(d, out)
    again = dm.load_design(out)
    assert _rounded(dm.design_to_dict(again)) == _rounded(dm.design_to_dict(d))
    assert not (tmp_path / "d.json.tmp").exists()


def _mutated(path: list, value):
    data = copy.deepcopy(TV8)
    node = data
    for key in path[:-1]:
        node = node[key]
    if value is KeyError:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return data


@pytest.mark.parametrize(
    "path, value, field",
    [
        (["poses"], [], "poses"),
        (["poses", 1, "wxyz"], [0, 0, 0, 0], "poses[1].wxyz"),
        (["poses", 2, "position"], [1, "x", 3], "poses[2].position[1]"),
        (["poses", 0, "position"], KeyError, "poses[0].position"),
        (["poses", 3, "wxyz"], [1, 0, 0, float("nan")], "poses[3].wxyz[3]"),
        (["motion", "method"], "spline", "motion.method"),
        (["motion", "family"], 2, "motion.family"),
        (["motion", "mu"], "big", "motion.mu"),
        (["loop"], 9, "loop"),
        (["realization", "p"], 0, "realization.p"),
        (["realization", "fixed"], {"7": 0.0}, "realization.fixed.7"),
        (["inertia", "semi_axes"], [0, 0, 0], "inertia.semi_axes"),
        (["inertia", "weight"], -2, "inertia.weight"),
        (["version"], 7, "version"),
        (["colour"], "red", "design.colour"),
    ],
)
def test_bad_fields_are_named(path, value, field):
    with pytest.raises(DesignFileError) as info:
        dm.design_from_dict(_mutated(path, value))
    assert info.value.field == field
    assert str(info.value).startswith(field)


def test_criterion_parameters_are_required_and_used():
    with pytest.raises(DesignFileError) as info:
        dm.design_from_dict(_mutated(["motion", "criterion"], "end-axes"))
    assert info.value.field == "motion.targets"
    data = _mutated(["motion", "criterion"], "end-axes")
    data["motion"]["targets"] = [[0, 0, 0], [1, 0, 0]]
    d = dm.design_from_dict(data)
    assert d.motion.targets.shape == (2, 3)
    with pytest.raises(DesignFileError) as info:
        dm.design_from_dict(_mutated(["motion", "criterion"], "extra-poses"))
    assert info.value.field == "motion.extra_poses"


def test_pose_count_must_match_method_when_solving():
    from paraloop_core import pipeline

    data = _mutated(["poses"], TV8["poses"] + [TV8["poses"][1]])
    d = dm.design_from_dict(data)  # an edit in progress still loads (and autosaves)
    with pytest.raises(DesignFileError, match="exactly 4") as info:
        pipeline.solve(d)
    assert info.value.field == "poses"
    data["motion"]["method"] = "fit"
    data["poses"] = TV8["poses"]
    with pytest.raises(DesignFileError, match="at least 5"):
        pipeline.solve(dm.design_from_dict(data))


def test_unreadable_files(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{ not json")
    with pytest.raises(DesignFileError, match="not valid JSON"):
        dm.load_design(bad)
    with pytest.raises(DesignFileError, match="cannot read"):
        dm.load_design(tmp_path / "missing.json")
