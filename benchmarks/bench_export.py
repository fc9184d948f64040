"""Plain ``paraloop export`` of the examples (issue 27: <= 5 s each on 2 cores): wall time and
CPU time (user + sys of the child process, all its threads) per run, start-up included.

Run: ``.venv/bin/python benchmarks/bench_export.py [DESIGN.json ...] [--repeat 3]`` (default
tv8 and sun-disc). Prints figures; asserts nothing. On a shared machine the wall time follows
the load; the CPU time is the steadier figure.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ("assets/designs/tv8.json", "assets/designs/sun-disc.json")


def one_export(design: Path, out: Path) -> tuple[float, float, int]:
    """``(wall s, CPU s, exit status)`` of one ``paraloop export`` run in a child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "app.cli.main", "export", str(design), "--out",
                           str(out), "--force", "--quiet"], cwd=ROOT, capture_output=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu, done.returncode


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("designs", nargs="*", default=list(EXAMPLES))
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.designs:
            design = (ROOT / name).resolve()
            runs = [one_export(design, Path(tmp) / design.stem) for _ in range(args.repeat)]
            walls = ", ".join(f"{w:.2f}" for w, _, _ in runs)
            cpus = ", ".join(f"{c:.2f}" for _, c, _ in runs)
            codes = sorted({code for *_, code in runs})
            print(f"{design.name}: wall {walls} s (best {min(w for w, _, _ in runs):.2f}); "
                  f"CPU {cpus} s (best {min(c for _, c, _ in runs):.2f}); exit {codes}")


if __name__ == "__main__":
    main()
