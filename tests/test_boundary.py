"""The command line's boundary (issue 27 items 2 and 6): a command imports only what it needs;
every refused case is one line naming the field and its range with values in JSON spelling,
exit 2 and nothing written; no NaN or Infinity in a result and no numpy warning on stderr;
outputs are probed before the work, created with the umask's mode, and never ``""``."""

from __future__ import annotations

import copy
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import numeric_paths
from hypothesis import given
from hypothesis import strategies as st

from app.cli.main import main
from paraloop_core import design as dm
from paraloop_core import pipeline
from paraloop_core.errors import DesignFileError, ParaloopError, shown

ROOT = Path(__file__).resolve().parents[1]
ASSETS = ROOT / "assets" / "designs"
TV8 = json.loads((ASSETS / "tv8.json").read_text())
ARC = json.loads((ASSETS / "arc-sculpture.json").read_text())
HEAVY = ("viser", "trimesh", "manifold3d", "dask", "distributed")


def _run(*args: str, cwd: Path = ROOT, umask: int | None = None) -> subprocess.CompletedProcess:
    """``python -c`` in a fresh interpreter (the start-up state matters here)."""
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=300,
                          cwd=cwd, preexec_fn=None if umask is None else lambda: os.umask(umask))


def _loaded_after(argv: list[str]) -> list[str]:
    code = (f"import sys; from app.cli.main import main; code = main({argv!r}); "
            f"print(code, [m for m in {HEAVY!r} if m in sys.modules], file=sys.stderr)")
    proc = _run("-c", code)
    code, heavy = proc.stderr.strip().splitlines()[-1].split(" ", 1)
    assert code == "0", proc.stderr
    return eval(heavy)  # a list literal printed above


def test_solve_never_imports_the_studio_or_mesh_libraries(tmp_path):
    """``paraloop solve`` (its --help and a solve with realization) loads none of viser,
    trimesh, manifold3d, dask; ``--help`` lists every command all the same."""
    assert _loaded_after(["solve", "--help"]) == []
    assert _loaded_after(["solve", str(ASSETS / "tv8.json"), "-o", str(tmp_path / "r.json")]) \
        == []
    assert (tmp_path / "r.json").is_file()
    proc = _run("-m", "app.cli.main", "--help")
    assert proc.returncode == 0
    for command in ("solve", "validate", "studio", "export", "animate"):
        assert command in proc.stdout
    assert "realization" in _run("-m", "app.cli.main", "validate", "--help").stdout
    assert "--printer" in _run("-m", "app.cli.main", "export", "--help").stdout


# --- the design file: numbers of any size, JSON spelling ---------------------------------------



EVOLUTION = ("w0", "q", "tol", "loop_ratio", "smooth_drive", "max_iterations", "starts", "seed",
             "workers", "virtual")
DRIVE = ("motor", "cycle_time_s", "max_speed_ratio", "max_accel_rad_s2", "density_kg_m3")


def _with(data: dict, path: tuple, value) -> dict:
    out = copy.deepcopy(data)
    node = out
    for k in path[:-1]:
        node = node.setdefault(k, {}) if isinstance(node, dict) else node[k]
    node[path[-1]] = value
    return out


def _every_numeric_field() -> list[tuple]:
    base = {**TV8, "end_effector": {"shape": "disc", "scale": 1.0, "L": 1, "R": 2,
                                    "clearance": 0.01},
            "realization": {**TV8.get("realization", {}), "rho": 0.01, "d": 0.05,
                            "fixed": {"0": 0.5}}}
    paths = set(numeric_paths(base))
    paths |= {("evolution", k) for k in EVOLUTION} | {("drive", k) for k in DRIVE}
    paths |= {("motion", "mu"), ("loop",)}
    return sorted(paths, key=str), base


PATHS, BASE = _every_numeric_field()


@pytest.mark.parametrize("value", [10**400, -(10**400), 10**5000, 2**64, 1e308, -1e308],
                         ids=["1e400", "-1e400", "1e5000", "2^64", "1e308", "-1e308"])
def test_numbers_of_any_size_in_every_numeric_field(value):
    """Integers of any size (and huge floats) anywhere: a DesignFileError naming that field and
    the accepted range, with the value shown bounded; never OverflowError."""
    refused = 0
    for path in PATHS:
        try:
            dm.design_from_dict(_with(BASE, path, value))
        except DesignFileError as exc:
            msg = str(exc)
            field = ".".join(str(k) for k in path if not isinstance(k, int))
            assert exc.field.replace("[", ".").startswith(field.split(".")[0]), (path, msg)
            assert "\n" not in msg and len(msg) < 400, msg
            assert any(w in msg for w in ("..", "[", "(", "at most", "one of", "the integer")), msg
            refused += 1
        else:  # only a few fields take any magnitude (a quaternion is normalized)
            assert path[-2:-1] == ("wxyz",) or path[:1] == ("poses",), (path, value)
    assert refused >= len(PATHS) - 16  # the poses' wxyz components scale freely


@pytest.mark.parametrize("edit, words", [
    ((("realization", "enabled"), None), "got null"),
    ((("loop",), True), "got true"),
    ((("motion", "family"), False), "got false"),
    ((("end_effector",), {"shape": "cube"}), 'one of "disc", "panel", got "cube"'),
    ((("motion", "criterion"), "x" * 100), '"xxxxxxxx'),
    ((("evolution", "init"), None), 'must be "random" or "four-pose", got null'),
    ((("name",), ["a"]), 'got ["a"]'),
])
def test_values_are_shown_in_json_spelling(edit, words):
    with pytest.raises(DesignFileError) as info:
        dm.design_from_dict(_with(TV8, *edit))
    msg = str(info.value)
    assert words in msg, msg
    assert not any(w in msg for w in ("True", "None", "False", "'")), msg


# --- the command line: one line, exit 2, nothing written -----------------------------------------
def _arc_tiny_disc() -> dict:
    """arc-sculpture at 1e6 times its size with a disc end-effector of scale 1e-12 (issue 27:
    once a ``found`` realization with NaN clearances)."""
    d = copy.deepcopy(ARC)
    for p in d["poses"]:
        p["position"] = [x * 1e6 for x in p["position"]]
    d["end_effector"] = {"shape": "disc", "scale": 1e-12}
    return d


CASES = {
    "long-mesh": (_with(TV8, ("end_effector",), {"mesh": "a" * 4096}), "end_effector.mesh"),
    "absolute-mesh": (_with(TV8, ("end_effector",), {"mesh": "/etc/passwd"}),
                      "end_effector.mesh"),
    "escaping-mesh": (_with(TV8, ("end_effector",), {"mesh": "../../../etc/hosts"}),
                      "end_effector.mesh"),
    "rho": (_with(TV8, ("realization",), {"rho": 1.0}), "realization.rho"),
    "rho-fraction": (_with(TV8, ("realization",), {"rho_fraction": 0.9}),
                     "realization.rho_fraction"),
    "panel-L": (_with(TV8, ("end_effector",), {"shape": "panel", "L": 9}), "end_effector.L"),
    "fixed": (_with(TV8, ("realization",), {"fixed": {str(i): 0.0 for i in range(6)}}),
              "realization.fixed"),
    "w0": (_with(TV8, ("evolution", "w0"), 10**400), "evolution.w0"),
    "tv8-1e9": (_with(TV8, ("poses", 1, "position", 0), 1e9), "non-generic motion"),
    "arc-tiny-disc": (_arc_tiny_disc(), "end_effector.scale"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_refused_cases_are_one_line_exit_2_nothing_written(case, tmp_path, capsys):
    data, words = CASES[case]
    path = tmp_path / "design.json"
    path.write_text(json.dumps(data))
    out = tmp_path / "out"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a numpy RuntimeWarning fails the case
        code = main(["solve", str(path), "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2, err
    assert len(err) == 1 and err[0].startswith(f"error: {path}: ") and words in err[0], err
    assert "internal error" not in err[0] and "cannot write" not in err[0]
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["design.json"]


def test_mesh_refusal_does_not_tell_whether_a_file_exists(tmp_path):
    """An absolute or escaping mesh path gets the same message whether or not its file
    exists (the studio's server must not answer that question)."""
    secret = tmp_path / "outside" / "secret.stl"
    secret.parent.mkdir()
    secret.write_bytes((ROOT / "assets" / "meshes" / "shading-panel.stl").read_bytes())
    folder = tmp_path / "designs"
    folder.mkdir()

    def message(mesh: str) -> str:
        data = _with(TV8, ("end_effector",), {"mesh": mesh})
        with pytest.raises(DesignFileError) as info:
            dm.load_design_bytes(json.dumps(data).encode(), base_dir=folder)
        return str(info.value).replace(shown(mesh), "<mesh>")

    said = {message(m) for m in (str(secret), str(secret.with_name("none.stl")),
                                 "../outside/secret.stl", "../outside/none.stl")}
    assert len(said) == 1, said


def test_a_path_that_is_not_a_regular_file_is_not_called_missing(tmp_path, capsys):
    folder = tmp_path / "d"
    (folder / "mesh.stl").mkdir(parents=True)
    path = folder / "design.json"
    path.write_text(json.dumps(_with(TV8, ("end_effector",), {"mesh": "mesh.stl"})))
    assert main(["solve", str(path), "-o", str(tmp_path / "o.json")]) == 2
    err = capsys.readouterr().err
    assert "end_effector.mesh" in err and "not a regular file" in err and "not found" not in err
    assert main(["solve", str(folder), "-o", str(tmp_path / "o.json")]) == 2
    err = capsys.readouterr().err
    assert "is a directory" in err and "not found" not in err


def test_non_finite_values_never_reach_a_result():
    """The last guard: a NaN in a result is a NumericalError naming where, not a file with
    NaN or an internal error."""
    from paraloop_core.errors import NumericalError
    from paraloop_core.result import raise_non_finite, write_json_atomic

    raise_non_finite({"a": [1.0, {"b": 2}]})
    with pytest.raises(NumericalError, match=r"result\.loops\[1\]\.singularity is nan"):
        raise_non_finite({"loops": [{"singularity": 1.0}, {"singularity": float("nan")}]})
    with pytest.raises(NumericalError):
        write_json_atomic(Path("/nonexistent/never.json"), {"x": float("inf")})


_JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=5),
    lambda kids: st.lists(kids, max_size=4) | st.dictionaries(st.text(max_size=4), kids,
                                                              max_size=4),
    max_leaves=25)


@given(_JSON)
def test_result_json_text_is_the_same_json(data):
    """The fast writer's text reads back as ``json.dumps`` of the same data does (key order,
    numbers to the last bit, strings)."""
    from paraloop_core.result import json_text

    text = json_text(data)
    assert text.endswith("\n") and json.loads(text) == json.loads(json.dumps(data))
    assert json.dumps(json.loads(text)) == json.dumps(data)


# --- outputs ------------------------------------------------------------------------------------
def test_empty_output_paths_are_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    tv8 = str(ASSETS / "tv8.json")
    for argv in (["solve", tv8, "-o", ""], ["export", tv8, "--out", ""],
                 ["animate", tv8, "--out", ""]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "empty path" in err[0], err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs /proc")
def test_unwritable_targets_are_refused_before_the_work(tmp_path, capsys, monkeypatch):
    """The output check writes a probe file: /proc is refused up front (as root too, where
    os.access says yes), naming the folder and never a temporary file."""
    def never(*a, **k):
        raise AssertionError("solved before the output was checked")

    monkeypatch.setattr(pipeline, "solve", never)
    tv8 = str(ASSETS / "tv8.json")
    for argv in (["solve", tv8, "-o", "/proc/paraloop.json"],
                 ["solve", tv8, "-o", "/proc/paraloop-out"],
                 ["export", tv8, "--out", "/proc/paraloop-parts"]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "/proc" in err[0] and "cannot write" in err[0], err
        assert ".tmp" not in err[0], err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("umask", [0o022, 0o077])
def test_results_follow_the_umask(tmp_path, umask):
    out = tmp_path / "out"
    proc = _run("-m", "app.cli.main", "solve", str(ASSETS / "tv8.json"),
                str(ASSETS / "sun-disc.json"), "-o", str(out), "--no-realize", umask=umask)
    assert proc.returncode == 0, proc.stderr
    for f in out.iterdir():
        assert f.stat().st_mode & 0o777 == 0o666 & ~umask, (f, oct(f.stat().st_mode))


def test_write_files_follow_the_umask(tmp_path):
    from app.cli import outputs

    old = os.umask(0o027)
    try:
        outputs.write_files(tmp_path / "parts", [("a.stl", b"x"), ("b.json", b"{}")])
    finally:
        os.umask(old)
    modes = {f.name: f.stat().st_mode & 0o777 for f in (tmp_path / "parts").iterdir()}
    assert modes == {"a.stl": 0o640, "b.json": 0o640}


# --- numbers: the places that once gave NaN -------------------------------------------------------
def test_unresolvable_norm_root_is_refused_not_nan():
    """tv8 with one position component 1e9 (inside the 1e12 range): a norm root 1.7e-9 of its
    size from the real line, which float64 cannot follow; refused as non-generic, where the
    singularity measure once divided by a zero norm."""
    design = dm.design_from_dict(_with(TV8, ("poses", 1, "position", 0), 1e9))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ParaloopError, match="non-generic motion within float64") as info:
            pipeline.solve(design, realize=False)
    assert info.value.reason == "real-root"


def test_end_effector_flattened_by_rounding_is_refused():
    from paraloop_core.realization import endeffector as eem

    body = eem.builtin("disc", 1e-12)
    ref = np.array([1.0, 0, 0, 0, 0, 5e5, 0, 0])  # 1e6 from the origin
    jf = pipeline.solve(dm.design_from_dict(TV8), realize=False).loop.joint_factors
    with pytest.raises(ParaloopError, match="float64 rounding") as info:
        eem.attach(body, ref, jf)
    assert info.value.param == "scale"
    eem.attach(eem.builtin("disc", 1e-3), ref, jf)  # a body of a sensible size is kept
