"""`paraloop solve` on good, malformed and degenerate design files (in-process and as a script)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.cli.main import main

ASSETS = Path(__file__).resolve().parents[1] / "assets" / "designs"


def _write(tmp_path: Path, name: str, data) -> Path:
    p = tmp_path / name
    p.write_text(data if isinstance(data, str) else json.dumps(data))
    return p


def test_solve_batch_writes_one_result_per_design(tmp_path):
    designs = sorted(ASSETS.glob("*.json"))
    out = tmp_path / "out"
    assert main(["solve", *map(str, designs), "-o", str(out), "--no-realize"]) == 0
    for d in designs:
        res = json.loads((out / f"{d.stem}.result.json").read_text())
        assert np.array(res["motion"]["coefficients"]).shape == (4, 8)
        assert len(res["factorizations"]) == 6 and len(res["loops"]) == 9


def test_solve_single_file_output_with_realization(tmp_path):
    out = tmp_path / "tv8.json"
    assert main(["solve", str(ASSETS / "tv8.json"), "-o", str(out)]) == 0
    res = json.loads(out.read_text())
    assert res["realization"]["min_clearance"] >= 2 * res["realization"]["radius"]


def test_malformed_design_names_field_and_writes_nothing(tmp_path, capsys):
    data = json.loads((ASSETS / "tv8.json").read_text())
    data["poses"][2]["wxyz"] = [0, 0, 0, 0]
    bad = _write(tmp_path, "bad.json", data)
    out = tmp_path / "res"
    assert main(["solve", str(bad), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "poses[2].wxyz" in err[0] and "nonzero" in err[0]
    assert not out.exists() or not any(out.iterdir())


def test_degenerate_design_coincident_poses(tmp_path, capsys):
    data = json.loads((ASSETS / "tv8.json").read_text())
    data["poses"][3] = data["poses"][1]
    bad = _write(tmp_path, "coincident.json", data)
    out = tmp_path / "r.json"
    assert main(["solve", str(bad), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "coincident" in err.lower() and not out.exists()


def test_batch_continues_past_a_bad_file(tmp_path, capsys):
    bad = _write(tmp_path, "broken.json", "{")
    out = tmp_path / "out"
    code = main(["solve", str(bad), str(ASSETS / "tv8.json"), "-o", str(out), "--no-realize"])
    assert code == 2
    assert (out / "tv8.result.json").exists() and not (out / "broken.result.json").exists()
    assert "not valid JSON" in capsys.readouterr().err


def test_console_script_runs(tmp_path):
    exe = Path(sys.executable).with_name("paraloop")
    out = tmp_path / "o.json"
    proc = subprocess.run([str(exe), "solve", str(ASSETS / "tv8.json"), "-o", str(out),
                           "--no-realize"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert out.exists()


# --- issue 13 items 5/6: output paths, exit codes, one-line errors ------------------------


def _one_error_line(capsys, *words: str) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: "), err
    assert "Traceback" not in err[0]
    for w in words:
        assert w in err[0], err[0]
    return err[0]


def _no_tmp(root: Path) -> None:
    assert not [p for p in root.rglob("*") if p.name.endswith(".tmp")]


def test_existing_output_refused_before_work_and_force_overwrites(tmp_path, capsys):
    out = tmp_path / "r.json"
    out.write_text("keep")
    argv = ["solve", str(ASSETS / "tv8.json"), "-o", str(out), "--no-realize"]
    assert main(argv) == 2
    _one_error_line(capsys, "already exists", "--force")
    assert out.read_text() == "keep"
    assert main([*argv, "--force"]) == 0
    assert json.loads(out.read_text())["format"] == "paraloop-result"
    _no_tmp(tmp_path)


def test_directory_named_like_a_json_file_is_used_as_a_directory(tmp_path):
    out = tmp_path / "x.json"
    out.mkdir()
    assert main(["solve", str(ASSETS / "tv8.json"), "-o", str(out), "--no-realize"]) == 0
    assert (out / "tv8.result.json").is_file()
    _no_tmp(tmp_path)


def test_unusable_output_paths(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    tv8 = str(ASSETS / "tv8.json")
    assert main(["solve", tv8, "-o", str(blocker / "sub"), "--no-realize"]) == 2
    _one_error_line(capsys, "not a directory")
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "tv8.result.json").mkdir()
    assert main(["solve", tv8, str(ASSETS / "sun-disc.json"), "-o", str(tmp_path / "d")]) == 2
    _one_error_line(capsys, "is a directory")
    assert main(["solve", tv8, "-o", tv8, "--force"]) == 2
    _one_error_line(capsys, "would overwrite the input")
    _no_tmp(tmp_path)


def test_same_stem_inputs_refused_before_work(tmp_path, capsys):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    for d in ("a", "b"):
        (tmp_path / d / "x.json").write_text((ASSETS / "tv8.json").read_text())
    out = tmp_path / "out"
    argv = ["solve", str(tmp_path / "a" / "x.json"), str(tmp_path / "b" / "x.json"), "-o",
            str(out), "--no-realize"]
    assert main(argv) == 2
    _one_error_line(capsys, "would both write", "x.result.json")
    assert not out.exists()
    assert main(["solve", str(ASSETS / "tv8.json"), str(ASSETS / "tv8.json"), "-o", str(out)]) == 2
    _one_error_line(capsys, "given twice")


def test_bad_designs_give_one_line_and_exit_2(tmp_path, capsys):
    import os

    data = json.loads((ASSETS / "tv8.json").read_text())
    cases = {
        "huge-int": json.dumps(data).replace('"loop": 1', '"loop": ' + "7" * 400),
        "nested": '{"poses": ' + "[" * 50_000 + "]" * 50_000 + "}",
        "nan": json.dumps(data).replace('"p": 10', '"p": NaN'),
        "version": json.dumps({**data, "version": 1.0}),
    }
    for name, text in cases.items():
        path = _write(tmp_path, f"{name}.json", text)
        assert main(["solve", str(path), "-o", str(tmp_path / "o.json")]) == 2, name
        _one_error_line(capsys, str(path))
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    assert main(["solve", str(fifo), "-o", str(tmp_path / "o.json")]) == 2
    _one_error_line(capsys, "not a regular file")
    assert not (tmp_path / "o.json").exists()
    _no_tmp(tmp_path)


def test_bom_design_solves(tmp_path):
    bom = tmp_path / "bom.json"
    bom.write_bytes(b"\xef\xbb\xbf" + (ASSETS / "tv8.json").read_bytes())
    assert main(["solve", str(bom), "-o", str(tmp_path / "o.json"), "--no-realize"]) == 0


def test_numeric_arguments_are_checked(tmp_path, capsys):
    for argv in (["validate", "realization", "--seed", "2.5"],
                 ["validate", "realization", "--workers", "0"],
                 ["validate", "evolution", "--max-iterations", "inf"],
                 ["validate", "evolution", "--workers", "2.5"],
                 ["export", str(ASSETS / "tv8.json"), "--out", str(tmp_path), "--size-mm", "nan"],
                 ["solve"]):
        assert main(argv) == 2, argv
        _one_error_line(capsys, "paraloop")


def test_core_argument_checks():
    from paraloop_core.errors import ParaloopError
    from paraloop_core.validation import fig16, table1

    with pytest.raises(ParaloopError, match="seed"):
        table1.run(1, 2.5)
    with pytest.raises(ParaloopError, match="max_iterations"):
        fig16.run(1, 5, 0, 1, float("inf"))


def test_export_refuses_unwritable_out_before_solving(tmp_path, capsys, monkeypatch):
    from paraloop_core import pipeline

    def boom(*a, **k):
        raise AssertionError("solved before checking --out")

    monkeypatch.setattr(pipeline, "solve", boom)
    blocker = tmp_path / "f"
    blocker.write_text("")
    assert main(["export", str(ASSETS / "tv8.json"), "--out", str(blocker)]) == 2
    _one_error_line(capsys, "not a directory")
    out = tmp_path / "parts"
    out.mkdir()
    (out / "report.json").write_text("{}")
    assert main(["export", str(ASSETS / "tv8.json"), "--out", str(out)]) == 2
    _one_error_line(capsys, "already exists")


def test_internal_error_is_one_line_and_traceback_only_with_debug(tmp_path, capsys,
                                                                  monkeypatch):
    from paraloop_core import pipeline

    def bug(*a, **k):
        raise KeyError("oops")

    monkeypatch.setattr(pipeline, "solve", bug)
    argv = ["solve", str(ASSETS / "tv8.json"), "-o", str(tmp_path / "o.json")]
    assert main(argv) == 1
    _one_error_line(capsys, "internal error", "KeyError", "--debug")
    assert main([*argv, "--debug"]) == 1
    assert "Traceback" in capsys.readouterr().err
    assert not (tmp_path / "o.json").exists()


def test_not_realized_exits_3(tmp_path, monkeypatch):
    from paraloop_core import pipeline

    real = pipeline.result_to_dict

    def not_found(sol):
        return {**real(sol), "realization": {"status": "not_found", "reason": "cap-reached"}}

    monkeypatch.setattr(pipeline, "result_to_dict", not_found)
    out = tmp_path / "o.json"
    assert main(["solve", str(ASSETS / "tv8.json"), "-o", str(out), "--no-realize"]) == 3
    assert json.loads(out.read_text())["realization"]["status"] == "not_found"
