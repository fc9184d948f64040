"""Printability of a plain ``paraloop export`` (issue 26): bundled examples and random designs.

Run: ``.venv/bin/python benchmarks/printability.py [--n 100] [--start 0] [--workers 2]``.
Each design is solved and exported exactly as ``paraloop export DESIGN --out DIR`` does
without flags; per design it prints the size, the thinnest bar and its length / width, the
predicted sag and torque deflection, the least pin engagement (in axle diameters), the base
(stands, centre-of-mass margin as a share of the plate), the largest support share, the
verification and the export time (a refused design: what its refusal says would work, a
larger bed or none); then the shares meeting the issue's criteria.
``--check DIR`` also writes each export into ``DIR/<design>/`` and measures its files with
the independent checker (``tests/independent/printed_check.py``: sections, joint profiles,
centre of mass over the cycle, print layout, clearance), printing its failures.
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from functools import partial
from multiprocessing import Pool
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

from independent.generic_designs import random_design  # noqa: E402
from independent.printed_check import check_export  # noqa: E402

import paraloop_core as pl  # noqa: E402
from paraloop_core import printed  # noqa: E402


def run_one(item: tuple[str, object], check: Path | None = None) -> dict:
    """Solve and export one design (path or random seed): a summary row; with ``check`` the
    files written to ``check/<design>`` and the independent checker's failures."""
    name, source = item
    t0 = time.perf_counter()
    row: dict = {"design": name}
    try:
        design = pl.load_design(source) if isinstance(source, Path) else \
            pl.design_from_dict(random_design(*source))
        sol = pl.solve(design)
        if sol.realization is None:
            return {**row, "outcome": "not realized", "time": time.perf_counter() - t0}
        files, rep, _ = printed.export(sol)
    except ValueError as exc:  # the CLI's refusals (FabricationError etc.)
        bed = re.search(r"--bed (\d+,\d+,\d+)", str(exc))
        remedy = f"--bed {bed[1]}" if bed else \
            "none (a larger print would not help)" if "would not help" in str(exc) else None
        return {**row, "outcome": f"refused: {' '.join(str(exc).split()[:16])}"
                + ("" if remedy is None else f" [what would work: {remedy}]"),
                "remedy": remedy, "time": time.perf_counter() - t0}
    v, b = rep["verification"], rep.get("base")
    stiff = rep["stiffness"]["links"]
    eng = min(min(j["engagement_diameters"]) for j in rep["joints"])
    return {**row, "outcome": "ok" if v["ok"] else "unverified", "gap_ok": v["gap_ok"],
            "size_mm": rep["sizing"]["size_mm"], "width_mm": min(rep["sizing"]["bar_width_mm"]),
            "lw": max(s["length_per_width"] for s in stiff),
            "sag_mm": max(s["sag_mm"] for s in stiff),
            "torque_mm": max((s["torque_deflection_mm"] or 0.0) for s in stiff),
            "hand": stiff[0]["torque_deflection_mm"] is None, "engage": eng,
            "stands": None if b is None else b["stands"],
            "margin": None if b is None else b["com_margin_share"],
            "support": max(p["support_share"] for p in rep["print_layout"]["parts"]),
            "min_gap_mm": v["min_non_adjacent_gap_mm"], "plates": rep["print_layout"]["plates"],
            "walls_ok": rep["walls"]["ok"], "loop_changed": rep["choice"]["loop"] !=
            rep["choice"]["design_loop"], "time": time.perf_counter() - t0,
            "failures": None if check is None else _checked(files, check / name)}


def _checked(files: list[tuple[str, bytes]], folder: Path) -> list[str]:
    """The independent checker's failures of the export ``files`` written to ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    for old in folder.iterdir():
        old.unlink()
    for fname, data in files:
        (folder / fname).write_bytes(data)
    return check_export(folder)["failures"]


def describe(r: dict) -> str:
    """The row's figures in one line."""
    base = "-" if r["stands"] is None else ("stands" if r["stands"] else "mount")
    margin = "" if r["margin"] is None else f" ({100 * r['margin']:.0f} %)"
    return (f" {r['size_mm']:.0f} mm, bars >= {r['width_mm']:.1f} mm, L/W <= {r['lw']:.0f}, "
            f"sag {r['sag_mm']:.2f} / " + ("by hand" if r["hand"] else
                                           f"torque {r['torque_mm']:.2f} mm") + ", engage "
            f"{r['engage']:.1f} d, base {base}{margin}, support {100 * r['support']:.0f} %, "
            f"gap {r['min_gap_mm']:.1f} mm, {r['plates']} plates"
            + ("" if meets(r) else "  << short of the criteria")
            + ("" if r["failures"] is None else
               "".join(f"\n      checker: {f}" for f in r["failures"]) or "\n      checker: ok"))


def meets(r: dict) -> bool:
    """The issue's done-when, as far as the report tells (the independent checker
    ``tests/independent/printed_check.py`` measures the files themselves)."""
    return (r["outcome"] == "ok" and r["gap_ok"] and r["width_mm"] >= 6.0 and r["lw"] <= 30
            and r["engage"] >= 1.5 and r["stands"] is not None and r["support"] <= 0.2
            and r["walls_ok"])


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100, help="random designs")
    ap.add_argument("--start", type=int, default=0, help="first random seed")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--no-examples", action="store_true")
    ap.add_argument("--scale", type=float, default=1.0,
                    help="unit of the random designs' positions (e.g. 1e-6, 1e8)")
    ap.add_argument("--check", type=Path, default=None, metavar="DIR",
                    help="write the exports here and run the independent checker on them")
    args = ap.parse_args(argv)
    items = [] if args.no_examples else [
        (p.stem, p) for p in sorted((ROOT / "assets" / "designs").glob("*.json"))]
    items += [(f"random-{s}", (s, args.scale)) for s in range(args.start, args.start + args.n)]
    pool = Pool(args.workers) if args.workers > 1 else None
    rows = []
    one = partial(run_one, check=args.check)
    for r in (pool.imap(one, items) if pool else map(one, items)):
        rows.append(r)
        extra = "" if "size_mm" not in r else describe(r)
        print(f"{r['design']:>14}: {r['outcome']}{extra} ({r['time']:.1f} s)", flush=True)
    if pool:
        pool.close()
    real = [r for r in rows if r["outcome"] != "not realized"]
    done = [r for r in real if "size_mm" in r]
    ok = sum(meets(r) for r in done)
    print(f"\n{len(rows)} designs, {len(real)} realized, {len(done)} exported, verified "
          f"{sum(r['outcome'] == 'ok' for r in done)}, meeting every criterion {ok} "
          f"({100 * ok / max(len(real), 1):.0f} % of the realized), standing "
          f"{sum(bool(r['stands']) for r in done)}; export time median "
          f"{np.median([r['time'] for r in real]):.1f} s, max "
          f"{max(r['time'] for r in real):.1f} s")
    refused = [r for r in real if r["outcome"].startswith("refused")]
    if refused:
        beds = sum(str(r.get("remedy")).startswith("--bed") for r in refused)
        print(f"refused {len(refused)}: {beds} name a larger bed that prints them, "
              f"{sum(str(r.get('remedy')).startswith('none') for r in refused)} say a larger "
              "print would not help")
    if args.check is not None:
        clean = sum(r["failures"] == [] for r in done)
        kinds: dict[str, int] = {}
        for r in done:
            for f in set(f.split(":")[0].split(" ")[0] for f in r["failures"]):
                kinds[f] = kinds.get(f, 0) + 1
        print(f"independent checker: {clean} of {len(done)} exports without a failure "
              f"({100 * clean / max(len(real), 1):.0f} % of the realized); designs failing by "
              f"kind: {kinds}")

if __name__ == "__main__":
    main()
