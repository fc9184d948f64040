"""Design format: round trip, examples load, every bad field is named."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

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


# --- issue 13 items 5/6: limits at the boundary (docs/design-format.md, "Limits") -------------


@pytest.mark.parametrize(
    "path, value, field, words",
    [
        (["poses", 0, "position", 0], int("9" * 400), "poses[0].position[0]", "1e+12"),
        (["realization", "d"], 1e300, "realization.d", "(0, 1e+12]"),
        (["realization", "d"], 1e5, "realization.d", "times the poses' extent"),
        (["realization", "rho"], 1e-300, "realization.rho", "extent"),
        (["realization", "p"], 5e-324, "realization.p", "[1, 10000]"),
        (["realization", "max_k"], 10**9, "realization.max_k", "1..1000"),
        (["realization", "max_k"], 2.0, "realization.max_k", "integer"),
        (["version"], 1.0, "version", "integer 1"),
        (["version"], True, "version", "integer 1"),
        (["loop"], 2.5, "loop", "0..8"),
        (["evolution"], {"max_iterations": float("inf")}, "evolution.max_iterations", "1..10000"),
        (["evolution"], {"seed": 2.5}, "evolution.seed", "integer"),
        (["evolution"], {"workers": 2.5}, "evolution.workers", "1..256"),
        (["evolution"], {"max_iterations": 2.5}, "evolution.max_iterations", "integer"),
        (["evolution"], {"foo": 1}, "evolution.foo", 'unknown key "foo" at evolution'),
        (["evolution"], {"starts": 1000, "max_iterations": 10000}, "evolution.max_iterations",
         "budget"),
        (["realization", "foo"], 1, "realization.foo", 'unknown key "foo" at realization'),
        (["name"], "x" * 2000, "name", "1000"),
        (["poses"], [TV8["poses"][0]] * 1001, "poses", "3..1000"),
        (["inertia", "weight"], 1e9, "inertia.weight", "1e+06"),
        (["end_effector"], {"mesh": "a\x00b"}, "end_effector.mesh", "NUL"),
        (["realization", "fixed"], {"٣": 0.0}, "realization.fixed.\\u0663", "0"),
    ],
    ids=lambda v: str(v)[:20],
)
def test_limits_name_field_and_range(path, value, field, words):
    with pytest.raises(DesignFileError) as info:
        dm.design_from_dict(_mutated(path, value))
    msg = str(info.value)
    assert info.value.field == field and "\n" not in msg and len(msg) < 300
    assert words in msg


def test_deep_nesting_is_refused_not_recursion(tmp_path):
    deep = tmp_path / "deep.json"
    deep.write_text('{"poses": ' + "[" * 100_000 + "]" * 100_000 + "}")
    with pytest.raises(DesignFileError, match="nested deeper than 16"):
        dm.load_design(deep)
    nested: list = []
    for _ in range(5000):
        nested = [nested]
    with pytest.raises(DesignFileError, match="nested deeper"):
        dm.design_from_dict({**TV8, "evolution": {"seed": nested}})


@pytest.mark.parametrize("text, words", [
    ('{"poses": NaN}', "NaN is not valid JSON"),
    ('{"poses": -Infinity}', "-Infinity is not valid JSON"),
    ('{"poses": 1' + "0" * 5000 + "}", "number literal"),
    ('{"name": "a", "name": "b"}', 'duplicate key "name"'),
    (b"\xff\xfe{}", "not UTF-8"),
])
def test_strict_json(tmp_path, text, words):
    f = tmp_path / "d.json"
    f.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(DesignFileError, match=words):
        dm.load_design(f)


def test_bom_accepted_and_big_or_special_files_refused(tmp_path):
    bom = tmp_path / "bom.json"
    bom.write_bytes(b"\xef\xbb\xbf" + (ASSETS / "tv8.json").read_bytes())
    assert dm.load_design(bom).name == TV8["name"]
    big = tmp_path / "big.json"
    big.write_bytes(b" " * (20 * 2**20))
    with pytest.raises(DesignFileError, match="over the limit"):
        dm.load_design(big)
    with pytest.raises(DesignFileError, match="directory"):
        dm.load_design(tmp_path)


def test_fifo_is_refused_without_blocking(tmp_path):
    import os

    fifo = tmp_path / "design.json"
    os.mkfifo(fifo)
    with pytest.raises(DesignFileError, match="not a regular file"):
        dm.load_design(fifo)


def test_shipped_schema_accepts_examples_and_matches_limits():
    import jsonschema
    schema = json.loads((Path(dm.__file__).with_name("design.schema.json")).read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    for path in ASSETS.glob("*.json"):
        jsonschema.validate(json.loads(path.read_text()), schema)
    props = schema["properties"]
    assert props["poses"]["maxItems"] == dm.chk.MAX_POSES
    assert props["realization"]["anyOf"][1]["properties"]["max_k"]["maximum"] == 1000
    assert schema["$defs"]["length"]["maximum"] == dm.chk.MAX_LENGTH


def test_save_refuses_non_finite_and_leaves_nothing(tmp_path):
    from dataclasses import replace

    import numpy as np

    d = dm.design_from_dict(TV8)
    bad = replace(d, inertia=replace(d.inertia, weight=float("nan")))
    out = tmp_path / "d.json"
    with pytest.raises(ValueError):
        dm.save_design(bad, out)
    assert list(tmp_path.iterdir()) == []
    assert np.isfinite(d.inertia.weight)


def test_drive_settings_round_trip_and_defaults(tmp_path):
    assert dm.design_from_dict(TV8).drive == dm.DriveSettings()  # no section: defaults
    drive = {"motor": 3, "cycle_time_s": 4.5, "max_speed_ratio": 2.5, "max_accel_rad_s2": 0.7,
             "density_kg_m3": 1000}
    d = dm.design_from_dict({**TV8, "drive": drive})
    assert d.drive == dm.DriveSettings(3, 4.5, 2.5, 0.7, 1000.0)
    dm.save_design(d, tmp_path / "d.json")
    again = dm.load_design(tmp_path / "d.json")
    assert again.drive == d.drive and dm.design_to_dict(again)["drive"] == drive
    partial = dm.design_from_dict({**TV8, "drive": {"max_speed_ratio": 3}})
    assert partial.drive == dm.DriveSettings(max_speed_ratio=3.0)
    crit = dm.design_from_dict(_mutated(["motion", "criterion"], "smooth-drive"))
    assert crit.motion.criterion == "smooth-drive"


@pytest.mark.parametrize("drive, field, words", [
    ({"motor": 6}, "drive.motor", "integer in 0..5, got 6"),
    ({"motor": 1.0}, "drive.motor", "integer in 0..5"),
    ({"motor": True}, "drive.motor", "integer in 0..5"),
    ({"cycle_time_s": 0.001}, "drive.cycle_time_s", "[0.01, 1e+06]"),
    ({"cycle_time_s": None}, "drive.cycle_time_s", "must be a number in [0.01, 1e+06]"),
    ({"max_speed_ratio": 0.99}, "drive.max_speed_ratio", "[1, 1000]"),
    ({"max_speed_ratio": "2"}, "drive.max_speed_ratio", "number in [1, 1000]"),
    ({"max_accel_rad_s2": 0}, "drive.max_accel_rad_s2", "(0, 1e+09]"),
    ({"max_accel_rad_s2": float("inf")}, "drive.max_accel_rad_s2", "finite"),
    ({"density_kg_m3": 0.5}, "drive.density_kg_m3", "[1, 100000]"),
    ({"torque": 1}, "drive.torque", 'unknown key "torque" at drive (allowed: cycle_time_s'),
    (None, "drive", "must be an object"),
], ids=lambda v: str(v)[:24])
def test_drive_errors_name_field_and_range(drive, field, words):
    with pytest.raises(DesignFileError) as info:
        dm.design_from_dict({**TV8, "drive": drive})
    msg = str(info.value)
    assert info.value.field == field and msg.startswith(field) and "\n" not in msg
    assert words in msg


_DRIVE_VALUES = st.sampled_from([None, 0, 1, 5, 6, -1, 0.0, 0.005, 0.01, 0.5, 1.0, 2.5, 10,
                                 1e3, 1e3 + 1, 1e5, 1e6, 1e9, 2e9, True, "1", [1]])


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.dictionaries(st.sampled_from(["motor", "cycle_time_s", "max_speed_ratio",
                                        "max_accel_rad_s2", "density_kg_m3", "x"]),
                       _DRIVE_VALUES, max_size=5))
def test_drive_loader_and_schema_agree(drive):
    import jsonschema
    schema = json.loads((Path(dm.__file__).with_name("design.schema.json")).read_text())
    data = {**TV8, "drive": drive}
    schema_ok = jsonschema.Draft202012Validator(schema).is_valid(data)
    try:
        dm.design_from_dict(data)
    except DesignFileError as exc:  # the schema's "integer" also takes 1.0: the loader not
        assert exc.field.startswith("drive")
        assert not schema_ok or exc.field == "drive.motor" and isinstance(drive["motor"], float)
    else:
        assert schema_ok
