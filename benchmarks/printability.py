"""Printability of a plain ``paraloop export`` (issue 14): bundled examples and random designs.

Run: ``.venv/bin/python benchmarks/printability.py [--n 100] [--workers 2]``. Each design is
solved and exported exactly as ``paraloop export DESIGN --out DIR`` does without flags
(generic printer profile); prints per design the outcome, the chosen size, the thinnest wall
(5th percentile of the local thickness over all parts), the largest part, the smallest verified
gap and the time, then the share exported, exported and verified, printable (no gap under half
the clearance), and meeting the walls and the bed.
"""

from __future__ import annotations

import argparse
import sys
import time
from multiprocessing import Pool
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

from independent.generic_designs import random_design  # noqa: E402

import paraloop_core as pl  # noqa: E402
from paraloop_core.fabrication import printable  # noqa: E402


def run_one(item: tuple[str, object]) -> dict:
    """Solve and export one design (path or random seed): a summary row."""
    name, source = item
    t0 = time.perf_counter()
    row: dict = {"design": name}
    try:
        design = pl.load_design(source) if isinstance(source, Path) else \
            pl.design_from_dict(random_design(int(source), 1.0))
        sol = pl.solve(design)
        real = sol.realization
        if real is None:
            return {**row, "outcome": "not realized", "time": time.perf_counter() - t0}
        res = printable.export_printable(
            real, effector=sol.end_effector, fixed=dict(design.realization.fixed),
            alternatives=sol.other_loops())
    except ValueError as exc:  # the CLI's refusals (FabricationError etc.)
        return {**row, "outcome": f"refused: {' '.join(str(exc).split()[:12])}",
                "time": time.perf_counter() - t0}
    ver, sz = res.report["verification"], res.report["sizing"]
    return {**row, "outcome": "ok" if ver["ok"] else "unverified", "printable": ver["printable"],
            "size_mm": sz["size_mm"], "wall_mm": res.report["walls"]["p5_mm"],
            "walls_ok": res.report["walls"]["ok"], "fits": all(sz["fits_bed"]),
            "largest_mm": float(np.max(printable.part_extents(res))),
            "min_gap_mm": ver["min_gap_mm"], "roomier": sz["realization"],
            "time": time.perf_counter() - t0}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100, help="random designs (seeds 0 .. n-1)")
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args(argv)
    items = [(p.stem, p) for p in sorted((ROOT / "assets" / "designs").glob("*.json"))]
    items += [(f"random-{s}", s) for s in range(args.n)]
    pool = Pool(args.workers) if args.workers > 1 else None
    rows = []
    for row in (pool.imap(run_one, items) if pool else map(run_one, items)):
        rows.append(row)
        extra = "" if "size_mm" not in row else (
            f" size {row['size_mm']:.0f} mm, wall p5 {row['wall_mm']:.2f} mm, largest part "
            f"{row['largest_mm']:.0f} mm, min gap {row['min_gap_mm']:.3f} mm"
            + ("" if row["walls_ok"] else "; WALLS UNDER THE PROFILE")
            + ("" if row["fits"] else "; NOT ON THE BED")
            + (f"; {row['roomier']}" if row.get("roomier") else ""))
        print(f"{row['design']:>16}: {row['outcome']}{extra} ({row['time']:.1f} s)", flush=True)
    if pool:
        pool.close()
    realized = [r for r in rows if r["outcome"] != "not realized"]
    done = [r for r in realized if "size_mm" in r]
    print(f"\n{len(rows)} designs, {len(realized)} realized: exported {len(done)} "
          f"({100 * len(done) / max(len(realized), 1):.1f} %), verified "
          f"{sum(r['outcome'] == 'ok' for r in done)}, printable "
          f"{sum(bool(r.get('printable')) for r in done)}, walls and bed fit met "
          f"{sum(bool(r.get('walls_ok') and r.get('fits')) for r in done)}; export time median "
          f"{np.median([r['time'] for r in realized]):.1f} s")


if __name__ == "__main__":
    main()
