"""`paraloop solve` on good, malformed and degenerate design files (in-process and as a script)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

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
    assert main(["solve", str(bad), "-o", str(out)]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "poses[2].wxyz" in err[0] and "nonzero" in err[0]
    assert not out.exists() or not any(out.iterdir())


def test_degenerate_design_coincident_poses(tmp_path, capsys):
    data = json.loads((ASSETS / "tv8.json").read_text())
    data["poses"][3] = data["poses"][1]
    bad = _write(tmp_path, "coincident.json", data)
    out = tmp_path / "r.json"
    assert main(["solve", str(bad), "-o", str(out)]) != 0
    err = capsys.readouterr().err
    assert "coincident" in err.lower() and not out.exists()


def test_batch_continues_past_a_bad_file(tmp_path, capsys):
    bad = _write(tmp_path, "broken.json", "{")
    out = tmp_path / "out"
    code = main(["solve", str(bad), str(ASSETS / "tv8.json"), "-o", str(out), "--no-realize"])
    assert code != 0
    assert (out / "tv8.result.json").exists() and not (out / "broken.result.json").exists()
    assert "not valid JSON" in capsys.readouterr().err


def test_console_script_runs(tmp_path):
    exe = Path(sys.executable).with_name("paraloop")
    out = tmp_path / "o.json"
    proc = subprocess.run([str(exe), "solve", str(ASSETS / "tv8.json"), "-o", str(out),
                           "--no-realize"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert out.exists()
