"""Studio latency: server-side time from a gizmo event to the scene being updated.

Run: ``.venv/bin/python benchmarks/bench_studio.py [--repeats N]``. Prints medians and 90th
percentiles of: drag preview (motion, six factorizations, nine loops' singularity, axes),
release (full update with the realized loop), and the motion slider (one animation frame), plus
the core-function share of each. Targets: preview <= 20 ms, full <= 80 ms (medians).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
from pathlib import Path

import numpy as np
import viser

from app import studio as studio_mod
from app.worker import FRAME, FULL, PREVIEW
from paraloop_core import design as design_mod
from paraloop_core import pipeline

DESIGN = Path(__file__).resolve().parent.parent / "assets" / "designs" / "tv8.json"


def _fire(app: studio_mod.Studio, i: int, position: np.ndarray, phase: str) -> float:
    """Seconds from the gizmo callback to the worker being idle (scene drawn)."""
    g = app.scene.gizmos[i]
    g.position = position
    event = viser.TransformControlsEvent(None, None, g, phase)
    start = time.perf_counter()
    app._on_gizmo(i, event)  # what the gizmo's async callback runs on viser's event loop
    assert app.worker.wait_idle(60)
    return time.perf_counter() - start


def _stats(name: str, secs: list[float]) -> None:
    ms = 1e3 * np.asarray(secs)
    print(f"{name:<44} median {np.median(ms):7.1f} ms   p90 {np.percentile(ms, 90):7.1f} ms"
          f"   (n={len(ms)})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=30)
    args = parser.parse_args()
    design = dataclasses.replace(design_mod.load_design(DESIGN), locked=(0, 1, 2))
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = studio_mod.Studio(server, design, None)
    assert app.worker.wait_idle(60)
    rng = np.random.default_rng(0)
    base = design.poses[3].position
    moves = [base + 0.03 * rng.normal(size=3) for _ in range(args.repeats)]
    try:
        for t in app.timings.values():
            t.clear()
        preview = [_fire(app, 3, p, "update") for p in moves]
        jobs_preview = list(app.timings[PREVIEW])
        full = [_fire(app, 3, p, "end") for p in moves[: max(5, args.repeats // 2)]]
        jobs_full = list(app.timings[FULL])
        frames = []
        for u in np.linspace(0.01, 0.99, args.repeats):
            start = time.perf_counter()
            app.panels.u.value = float(u)
            app.worker.wait_idle(60)
            frames.append(time.perf_counter() - start)
        solve_fast = [_time(lambda: pipeline.solve(app.state.design, realize=False))
                      for _ in range(10)]
        solve_full = [_time(lambda: pipeline.solve(app.state.design, realize=True))
                      for _ in range(5)]
    finally:
        app.close()
        server.stop()
    print(f"design {DESIGN.name}, loop {design.loop}, viser {viser.__version__}, "
          f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    _stats("gizmo drag -> preview drawn (target 20 ms)", preview)
    _stats("  worker job (solve + draw)", jobs_preview)
    _stats("  pipeline.solve(realize=False)", solve_fast)
    _stats("gizmo release -> full update (target 80 ms)", full)
    _stats("  worker job (solve + realize + draw + plots)", jobs_full)
    _stats("  pipeline.solve(realize=True)", solve_full)
    _stats("motion slider -> frame drawn", frames)
    _stats("  worker job (frame)", app.timings[FRAME])


def _time(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


if __name__ == "__main__":
    main()
