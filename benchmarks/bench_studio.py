"""Studio latency: server-side time from a gizmo event to the scene being updated.

Run: ``.venv/bin/python benchmarks/bench_studio.py [--repeats N] [--design FILE ...]``. For
every bundled example (or the given designs) prints medians and 90th percentiles of: a drag
step (preview: motion, six factorizations, nine loops' singularity and the last realization
moved along when its exact minima clear, see ``pipeline.warm_preview``) and the share of drag
steps that showed the linkage; the full update on release (realization warm-started from the
last one, certified; when the quick search finds nothing, the full search follows as a
background job, timed apart); far drags released; and the motion slider (one animation frame).
Targets (issue 15): drag updates <= 100 ms, far drags <= 300 ms (medians).
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
from app.scene import design_scale
from paraloop_core import design as design_mod

EXAMPLES = Path(__file__).resolve().parent.parent / "assets" / "designs"
DESIGN = EXAMPLES / "tv8.json"


def _fire(app: studio_mod.Studio, i: int, position: np.ndarray, phase: str
          ) -> tuple[float, float]:
    """Seconds from the gizmo callback to the scene drawn (the worker idle, or on release
    the full update drawn; a background job may follow: a fit design's multi-start fit, the
    full realization search when the quick one found nothing) and to the worker idle."""
    g = app.scene.gizmos[i]
    g.position = position
    event = viser.TransformControlsEvent(None, None, g, phase)
    drawn = len(app.timings[studio_mod.FULL])
    start = time.perf_counter()
    app._on_gizmo(i, event)  # what the gizmo's async callback runs on viser's event loop
    if phase == "end":
        while len(app.timings[studio_mod.FULL]) == drawn and time.perf_counter() - start < 60:
            time.sleep(0.0005)
        secs = time.perf_counter() - start
    assert app.worker.wait_idle(60)
    idle = time.perf_counter() - start
    return (secs if phase == "end" else idle), idle


def _stats(name: str, secs: list[float]) -> None:
    ms = 1e3 * np.asarray(secs)
    print(f"{name:<44} median {np.median(ms):7.1f} ms   p90 {np.percentile(ms, 90):7.1f} ms"
          f"   (n={len(ms)})")


def drag(app: studio_mod.Studio, i: int, path: list[np.ndarray]) -> dict[str, list[float]]:
    """One continuous drag of gizmo ``i`` along ``path`` and its release: the preview times,
    whether each preview showed the linkage, and the release's full-update time."""
    preview, shown = [], []
    for p in path:
        preview.append(_fire(app, i, p, "update")[0])
        shown.append(app.solver.preview is not None)
    full, final = _fire(app, i, path[-1], "end")
    return {"preview": preview, "shown": shown, "full": [full], "final": [final]}


def bench_design(path: Path, repeats: int) -> None:
    """Drags on the last free target of one example: small continuous steps (1 % of the
    design's size), then far jumps (15 %), each released."""
    design = design_mod.load_design(path)
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = studio_mod.Studio(server, design, None)
    assert app.worker.wait_idle(120)
    rng = np.random.default_rng(0)
    i = max(k for k in range(len(design.poses)) if k not in design.locked)
    scale = design_scale(design)
    base = design.poses[i].position
    near: dict[str, list] = {"preview": [], "shown": [], "full": [], "final": []}
    far: dict[str, list] = {"full": [], "final": []}
    try:
        for _ in range(repeats):
            step = 0.01 * scale * rng.normal(size=3) / np.sqrt(3)
            res = drag(app, i, [base + step * (k + 1) for k in range(5)])
            for key in near:
                near[key] += res[key]
        for _ in range(max(3, repeats // 2)):
            res = drag(app, i, [base + 0.15 * scale * rng.normal(size=3) / np.sqrt(3)])
            for key in far:
                far[key] += res[key]
    finally:
        app.close()
        server.stop()
    refine = app.timings[studio_mod.REFINE]
    print(f"\n== {path.name} (target {i}, size {scale:.3g}) ==")
    _stats("drag step -> preview drawn (target 100 ms)", near["preview"])
    print(f"  previews showing the linkage: {100 * np.mean(near['shown']):.0f} %")
    _stats("release after a short drag -> full update", near["full"])
    _stats("far drag released -> full update (300 ms)", far["full"])
    _stats("far drag released -> background job done too", far["final"])
    if refine:
        _stats("background job (multi-start fit, full search)", refine)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=10)
    parser.add_argument("--design", nargs="*", help="design files (default: every example)")
    args = parser.parse_args()
    paths = [Path(p) for p in args.design] if args.design else sorted(EXAMPLES.glob("*.json"))
    print(f"viser {viser.__version__}, load average {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} cores")
    for path in paths:
        bench_design(path, args.repeats)
    design = dataclasses.replace(design_mod.load_design(DESIGN), locked=(0, 1, 2))
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    app = studio_mod.Studio(server, design, None)
    assert app.worker.wait_idle(60)
    frames = []
    try:
        for u in np.linspace(0.01, 0.99, 30):
            start = time.perf_counter()
            app.panels.u.value = float(u)
            app.worker.wait_idle(60)
            frames.append(time.perf_counter() - start)
    finally:
        app.close()
        server.stop()
    print()
    _stats("motion slider -> frame drawn (tv8)", frames)


def _time(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


if __name__ == "__main__":
    main()
