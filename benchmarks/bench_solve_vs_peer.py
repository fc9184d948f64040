"""``paraloop solve`` of random generic designs against the open peer ``rational-linkages``.

    .venv/bin/python benchmarks/bench_solve_vs_peer.py [--designs 101] [--peer-python PY]

Prints figures; asserts nothing. Designs: ``tests/independent/generic_designs.py`` (seeds 0..,
realization off). Ours: wall time of ``paraloop solve`` of all designs minus that of one design
(start-up), per design, result files written (best of ``--repeat``), and in-process the core
(``pipeline.solve``) and ``save_result`` per design. Peer: its six factorizations of the same
world motions (``motion.coefficients`` of our result files: norm polynomial, its irreducible
factors by ``biquaternion_py``, ``factorize_from_list`` for every order of the three, axes by
``rational_linkages``' ``FactorizationProvider``), run by ``--peer-python``, an interpreter with
``rational-linkages`` installed (a throw-away venv; default ``$PARALOOP_PEER_PYTHON``). Without
it the peer part is skipped with a message.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

from independent.generic_designs import random_design  # noqa: E402

from paraloop_core import design, pipeline, result  # noqa: E402

#: Runs in the peer's interpreter: argv[1] a JSON file of motions (N, 4, 8) ascending in t,
#: [w x y z | dual]; prints seconds per motion and how many factorizations each gave.
PEER = r"""
import itertools, json, sys, time
import biquaternion_py as bq
from sympy import Symbol
from rational_linkages.FactorizationProvider import FactorizationProvider

def six(coeffs, prov, t):
    expr = sum((bq.BiQuaternion([float(v) for v in c]) * t**k for k, c in enumerate(coeffs)),
               bq.BiQuaternion([0] * 8))
    poly = bq.polynomials.Poly(expr, t)
    norm = poly.norm()
    norm = bq.polynomials.Poly(norm.poly.scal, *norm.indets)
    _, factors = bq.irreducible_factors(norm, domain="RR")
    return [[prov.factor2rotation_axis(f).array() for f in bq.factorize_from_list(poly, list(p))]
            for p in itertools.permutations(factors)]

motions = json.load(open(sys.argv[1]))
prov, t = FactorizationProvider(), Symbol("t")
counts, times = [], []
for m in motions:
    t0 = time.perf_counter()
    try:
        counts.append(len(six(m, prov, t)))
    except Exception:
        counts.append(0)
    times.append(time.perf_counter() - t0)
print(json.dumps({"seconds": times, "factorizations": counts}))
"""


def _paraloop() -> list[str]:
    exe = Path(sys.executable).with_name("paraloop")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "app.cli.main"]


def _solve_wall(files: list[Path], out: Path) -> float:
    """Wall seconds of one ``paraloop solve`` of ``files`` into the new folder ``out``."""
    t0 = time.perf_counter()
    run = subprocess.run([*_paraloop(), "solve", *map(str, files), "-o", str(out), "--force"],
                         capture_output=True, text=True, cwd=ROOT)
    dt = time.perf_counter() - t0
    if run.returncode != 0:
        raise SystemExit(f"paraloop solve failed ({run.returncode}): {run.stderr[-2000:]}")
    return dt


def _peer(python: str | None, motions: list, folder: Path) -> dict | str:
    """The peer's figures, or why they are missing."""
    if not python:
        return "no --peer-python (or $PARALOOP_PEER_PYTHON) given"
    if not Path(python).exists():
        return f"{python} does not exist"
    check = subprocess.run([python, "-c", "import rational_linkages, biquaternion_py"],
                           capture_output=True, text=True)
    if check.returncode != 0:
        return f"rational-linkages is not importable by {python}"
    data, script = folder / "motions.json", folder / "peer.py"
    data.write_text(json.dumps(motions))
    script.write_text(PEER)
    run = subprocess.run([python, str(script), str(data)], capture_output=True, text=True)
    if run.returncode != 0:
        return f"the peer failed: {run.stderr[-1000:]}"
    return json.loads(run.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--designs", type=int, default=101)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--peer-python", default=os.environ.get("PARALOOP_PEER_PYTHON"))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        files = []
        for seed in range(args.designs):
            path = folder / f"generic-{seed}.json"
            path.write_text(json.dumps(random_design(seed, 1.0, realization=False)))
            files.append(path)
        one = min(_solve_wall(files[:1], folder / f"one{k}") for k in range(args.repeat))
        many = min(_solve_wall(files, folder / f"all{k}") for k in range(args.repeat))
        per = (many - one) / (len(files) - 1)
        print(f"paraloop solve: 1 design {one:.3f} s, {len(files)} designs {many:.3f} s wall: "
              f"{per * 1e3:.2f} ms per design beyond start-up (result files written)")
        core, write = [], []
        for k, path in enumerate(files):
            d = design.load_design(path)
            sol = None
            best = np.inf
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                sol = pipeline.solve(d, realize=False)
                best = min(best, time.perf_counter() - t0)
            core.append(best)
            t0 = time.perf_counter()
            result.save_result(sol, folder / f"x{k}.result.json")  # a new file, as the CLI
            write.append(time.perf_counter() - t0)
        core_ms, write_ms = np.median(core) * 1e3, np.median(write) * 1e3
        print(f"in process: core (pipeline.solve) median {core_ms:.2f} ms, p95 "
              f"{np.percentile(core, 95) * 1e3:.2f} ms; result JSON written median "
              f"{write_ms:.2f} ms; solve per design / core = {per * 1e3 / core_ms:.2f}")
        motions = [json.loads((folder / "all0" / f"{p.stem}.result.json").read_text())
                   ["motion"]["coefficients"] for p in files]
        peer = _peer(args.peer_python, motions, folder)
    if isinstance(peer, str):
        print(f"peer (rational-linkages) skipped: {peer}")
        return
    secs = np.array(peer["seconds"])
    ok = np.array(peer["factorizations"]) == 6
    print(f"peer (rational-linkages): six factorizations of the same {len(secs)} motions: "
          f"median {np.median(secs):.3f} s, mean {secs.mean():.3f} s per motion "
          f"({ok.sum()} of {len(ok)} gave six)")
    print(f"ratio peer / ours (per design beyond start-up): mean {secs.mean() / per:.0f}x, "
          f"median {np.median(secs) / per:.0f}x")


if __name__ == "__main__":
    main()
