"""Fuzzing the input boundary (issue 13 items 5, 6): mutated example designs, as dicts, as files
(encodings, truncation, nesting) and through ``paraloop solve``. Only ParaloopError (a
ValueError with ``reason``) may come out of the core, the CLI only exits 0, 2 or 3 with
one-line messages, and no case may take long.

Default tier: a few hundred cases (< 30 s). Slow tier (``-m slow``): over 10 000 cases.
"""

from __future__ import annotations

import contextlib
import copy
import io
import json
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from app.cli.main import main
from paraloop_core import design as dm
from paraloop_core.errors import DesignFileError, ParaloopError

ASSETS = Path(__file__).resolve().parents[1] / "assets" / "designs"
BASES = {p.name: json.loads(p.read_text()) for p in sorted(ASSETS.glob("*.json"))}
#: four-pose designs solve in ~0.1 s without realization (the fit design takes seconds)
QUICK = [n for n, d in BASES.items() if d.get("motion", {}).get("method") != "fit"]
SCHEMA = json.loads(Path(dm.__file__).with_name("design.schema.json").read_text())

FAST = settings(max_examples=150, deadline=1000, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
SLOW = settings(FAST, max_examples=10_000, derandomize=False)


# --- strategies -------------------------------------------------------------------------------

odd_numbers = st.sampled_from([
    0, -1, 1, 2, 2.5, 1.0, True, False, 1e-300, 5e-324, -5e-324, 1e300, -1e300, 1e12, 1e12 + 1,
    float("inf"), float("-inf"), float("nan"), 2**53 + 1, 10**30, -(10**400), int("9" * 400),
    1e9, 10**9, 4.9e-324, 0.0, -0.0,
])
leaves = (st.none() | st.booleans() | st.integers() | odd_numbers
          | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=8)
          | st.sampled_from(["inf", "fit", "four-pose", "disc", "", "\x00", "\ud800", "0"]))
json_values = st.recursive(
    leaves,
    lambda kids: st.lists(kids, max_size=5) | st.dictionaries(st.text(max_size=6), kids,
                                                              max_size=4),
    max_leaves=12,
)
KEYS = ["foo", "p", "d", "rho", "max_k", "seed", "workers", "max_iterations", "starts", "mu",
        "position", "wxyz", "version", "format", "mesh", "shape", "0", "7", "fixed", "L",
        "drive", "motor", "cycle_time_s", "max_speed_ratio", "smooth_drive"]


def _paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _paths(v, (*prefix, i))


def _get(node, path):
    for k in path:
        node = node[k]
    return node


@st.composite
def mutated_designs(draw, names=tuple(BASES)):
    """An example design with 1..3 random edits: replace, delete, add a key, nest, repeat."""
    data = copy.deepcopy(BASES[draw(st.sampled_from(names))])
    for _ in range(draw(st.integers(1, 3))):
        paths = list(_paths(data))
        path = draw(st.sampled_from(paths))
        op = draw(st.sampled_from(["replace", "replace", "delete", "add", "nest", "repeat"]))
        if not path:
            if op == "add" and isinstance(data, dict):
                data[draw(st.sampled_from(KEYS))] = draw(json_values)
            continue
        parent, key = _get(data, path[:-1]), path[-1]
        value = parent[key]
        if op == "replace":
            parent[key] = draw(json_values)
        elif op == "delete":
            del parent[key]
        elif op == "add" and isinstance(value, dict):
            value[draw(st.sampled_from(KEYS))] = draw(json_values)
        elif op == "nest":
            for _ in range(draw(st.integers(1, 40))):
                value = [value]
            parent[key] = value
        elif op == "repeat" and isinstance(value, list):
            parent[key] = value * draw(st.integers(0, 300))
        if not isinstance(data, dict):
            break
    return data


def _dumps(data) -> str:
    return json.dumps(data, allow_nan=True, default=str)


@st.composite
def design_bytes(draw):
    """A mutated design serialized, then possibly mangled at the byte level."""
    text = _dumps(draw(mutated_designs()))
    how = draw(st.sampled_from(["plain", "bom", "utf16", "latin1", "truncate", "garbage",
                                "deep", "nan", "bigint", "empty"]))
    if how == "bom":
        return b"\xef\xbb\xbf" + text.encode()
    if how == "utf16":
        return text.encode("utf-16")
    if how == "latin1":
        return text.replace('"', '"\xe9', 1).encode("latin-1", "replace")
    if how == "truncate":
        return text.encode()[: draw(st.integers(0, len(text)))]
    if how == "garbage":
        raw = bytearray(text.encode())
        for _ in range(draw(st.integers(1, 5))):
            raw.insert(draw(st.integers(0, len(raw))), draw(st.integers(0, 255)))
        return bytes(raw)
    if how == "deep":
        n = draw(st.sampled_from([17, 100, 999, 1000, 5000, 200_000]))
        return ('{"poses": ' + "[" * n + "]" * n + "}").encode()
    if how == "nan":
        return text.replace("10", draw(st.sampled_from(["NaN", "Infinity", "-Infinity"])),
                            1).encode()
    if how == "bigint":
        return text.replace("1", "1" + "0" * draw(st.integers(20, 6000)), 1).encode()
    if how == "empty":
        return b""
    return text.encode()


# --- properties -------------------------------------------------------------------------------


def _check_error(exc: BaseException) -> None:
    assert isinstance(exc, ParaloopError), f"{type(exc).__name__}: {exc}"
    msg = str(exc)
    assert "\n" not in msg and len(msg) < 600, msg
    assert isinstance(exc.reason, str) and exc.reason
    if isinstance(exc, DesignFileError):
        assert msg.startswith(exc.field) and len(exc.field) < 200


def _schema_agrees(data) -> None:
    """Every design the loader accepts is valid under the shipped JSON Schema."""
    import jsonschema
    errors = list(jsonschema.Draft202012Validator(SCHEMA).iter_errors(data))
    assert not errors, errors[0].message


def check_design_dict(data) -> None:
    try:
        design = dm.design_from_dict(data)
    except Exception as exc:  # noqa: BLE001 - the property: only ParaloopError
        _check_error(exc)
        return
    _schema_agrees(data)
    dm.design_from_dict(json.loads(json.dumps(dm.design_to_dict(design), allow_nan=False)))


def check_design_file(raw: bytes) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.json"
        path.write_bytes(raw)
        try:
            dm.load_design(path)
        except Exception as exc:  # noqa: BLE001
            _check_error(exc)


def check_cli(data) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.json"
        path.write_text(_dumps(data), encoding="utf-8")
        out = Path(tmp) / "out.json"
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(["solve", str(path), "-o", str(out), "--no-realize"])
        lines = err.getvalue().splitlines()
        assert code in (0, 2, 3), (code, lines)
        assert all(ln.startswith(("error: ", "warning: ")) for ln in lines), lines
        assert (code == 2) == (not out.exists()), (code, lines)
        if code == 2:
            assert len(lines) == 1
        assert sorted(p.name for p in Path(tmp).iterdir()) == sorted(
            ["fuzz.json"] + (["out.json"] if out.exists() else []))
        if out.exists():
            json.loads(out.read_text(), parse_constant=lambda c: pytest.fail(c))


@FAST
@given(mutated_designs())
def test_fuzz_design_from_dict(data):
    check_design_dict(data)


@FAST
@given(design_bytes())
def test_fuzz_load_design(raw):
    check_design_file(raw)


@settings(FAST, max_examples=40, deadline=5000)
@given(mutated_designs(names=tuple(QUICK)))
def test_fuzz_cli_solve(data):
    check_cli(data)


@pytest.mark.slow
def test_fuzz_slow_tier():
    """10 000 dicts + 10 000 files + 1 000 CLI runs (``-m slow``)."""
    SLOW(given(mutated_designs())(check_design_dict))()
    SLOW(given(design_bytes())(check_design_file))()
    settings(SLOW, max_examples=1000, deadline=5000)(
        given(mutated_designs(names=tuple(QUICK)))(check_cli))()
