"""``--workers N`` / ``--dask ADDRESS``: the same files, bytes, messages and exit codes as a run
in one process (``app/cli/batch.py``)."""

from __future__ import annotations

import json
import logging
import os
import pickle
import time
from importlib import metadata
from pathlib import Path

import pytest
from distributed import LocalCluster

from app.cli import batch
from app.cli.main import main
from paraloop_core.errors import DesignFileError
from tests.independent.generic_designs import random_design

TV8 = Path(__file__).resolve().parents[1] / "assets" / "designs" / "tv8.json"


@pytest.fixture(scope="module")
def address():
    """A running cluster, as ``dask scheduler`` + ``dask worker`` would give."""
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address="127.0.0.1:0", silence_logs=logging.CRITICAL)
    try:
        yield cluster.scheduler_address
    finally:
        cluster.close()


@pytest.fixture(scope="module")
def designs(tmp_path_factory) -> list[Path]:
    """Random designs, the bundled TV8, one refused when read (a malformed field), one refused
    by its task (coincident poses: raised on the worker) and one solved but not realized."""
    d = tmp_path_factory.mktemp("designs")
    paths = []
    for seed in range(3):
        paths.append(d / f"g{seed}.json")
        paths[-1].write_text(json.dumps(random_design(seed)))
    malformed = random_design(7)
    malformed["loop"] = "three"
    tv8 = json.loads(TV8.read_text())
    coincident = json.loads(TV8.read_text())
    coincident["poses"][2] = coincident["poses"][1]
    fat = json.loads(TV8.read_text())
    fat["realization"].update(d_fraction=0.5, rho_fraction=0.5, max_k=1)
    for name, data in (("malformed", malformed), ("tv8", tv8), ("coincident", coincident),
                       ("fat", fat)):
        paths.append(d / f"{name}.json")
        paths[-1].write_text(json.dumps(data))
    return paths


def _run(argv: list[str], out: Path, capfd) -> tuple[int, str, str, dict[str, bytes]]:
    """Exit code, stdout and stderr (``out`` written as OUT; at the descriptors: a local
    cluster's workers write there) and the files written."""
    rc = main(argv)
    cap = capfd.readouterr()
    files = {f.name: f.read_bytes() for f in sorted(out.iterdir())} if out.is_dir() else {}
    return rc, cap.out.replace(str(out), "OUT"), cap.err.replace(str(out), "OUT"), files


def test_solve_on_a_cluster_writes_the_same_bytes(designs, address, tmp_path, capfd,
                                                  monkeypatch):
    names = [str(p) for p in designs]
    here = _run(["solve", *names, "-o", str(tmp_path / "here")], tmp_path / "here", capfd)
    rc, out, err, files = here
    assert rc == 2  # the most severe: refused (malformed, coincident) before not realized
    assert sorted(files) == ["fat.result.json", "g0.result.json", "g1.result.json",
                             "g2.result.json", "tv8.result.json"]
    assert "malformed.json: loop: must be an integer in 0..8" in err
    assert "coincident.json: poses 1 and 2 coincide" in err
    assert "fat.json: solved, but no collision-free realization" in err
    # one task in flight per worker: later designs finish first and wait for their turn
    monkeypatch.setattr(batch, "IN_FLIGHT_PER_WORKER", 1)
    remote = _run(["solve", *names, "-o", str(tmp_path / "remote"), "--dask", address],
                  tmp_path / "remote", capfd)
    assert remote == here
    monkeypatch.undo()
    local = _run(["solve", *names, "-o", str(tmp_path / "local"), "--workers", "2"],
                 tmp_path / "local", capfd)
    assert local == here


def test_outcomes_in_input_order_with_errors(address):
    items = ["1", "x", batch.Outcome(error=KeyError("read here")), "3"]
    for runner in (batch.Runner(), batch.Runner(address=address)):
        with runner:
            got = list(runner.outcomes(int, items))
            with pytest.raises(ValueError, match="invalid literal"):
                list(runner.values(int, items))
        assert [o.value for o in got] == [1, None, None, 3]
        assert [type(o.error) for o in got] == [type(None), ValueError, KeyError, type(None)]
        assert "invalid literal for int() with base 10: 'x'" in str(got[1].error)
    assert runner.workers == 2  # the cluster's threads


@pytest.mark.parametrize("bad", ["tcp://127.0.0.1:1", "notanaddress"])
def test_unreachable_scheduler_fails_fast_on_one_line(bad, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(batch, "CONNECT_TIMEOUT", 2.0)
    t0 = time.perf_counter()
    rc = main(["solve", str(TV8), "-o", str(tmp_path / "out"), "--dask", bad])
    err = capsys.readouterr().err
    assert rc == 2 and time.perf_counter() - t0 < 8.0
    assert err.count("\n") == 1 and err.startswith(f"error: --dask {bad}: cannot connect (")
    assert not (tmp_path / "out").exists()


def test_worker_with_another_paraloop_is_refused(address, tmp_path, capsys, monkeypatch):
    here, real = os.getpid(), metadata.version

    def version(name: str) -> str:  # pickled by value: the workers report their real one
        return "0.0.0-other" if os.getpid() == here else real(name)

    monkeypatch.setattr(metadata, "version", version)
    rc = main(["solve", str(TV8), "-o", str(tmp_path / "out"), "--dask", address])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1
    assert f"has paraloop {real('paraloop')}, this machine paraloop 0.0.0-other" in err


def test_validate_realization_same_rows_with_workers(address, tmp_path, capsys):
    runs = []
    for where in (["--workers", "1"], ["--workers", "2"], ["--dask", address]):
        path = tmp_path / f"rows{len(runs)}.csv"
        rc = main(["validate", "realization", "--motions", "2", "--seed", "3", "--quiet",
                   "--csv", str(path), *where])
        out = capsys.readouterr().out.splitlines()
        assert out[-1].endswith(("with 1 worker(s)", "with 2 worker(s)"))
        runs.append((rc, out[:-1], path.read_bytes()))  # the last line: time and workers
    assert runs[0][0] == 0 and runs[0][2].count(b"\n") == 1 + 4
    assert runs[1] == runs[0] and runs[2] == runs[0]


def test_design_file_error_survives_pickling():
    exc = pickle.loads(pickle.dumps(DesignFileError("poses[2]", "not a pose")))
    assert (str(exc), exc.field, exc.reason) == ("poses[2]: not a pose", "poses[2]",
                                                 "design-file")


def test_cli_options_are_exclusive(capsys):
    assert main(["solve", str(TV8), "-o", "x", "--workers", "2", "--dask", "tcp://a:1"]) == 2
    assert "not allowed with argument" in capsys.readouterr().err
