"""Independent checker of a ``paraloop export`` folder (issue 26, "Done when").

No ``paraloop_core`` import: the motion is read from the folder's ``result.json`` with this
package's own dual-quaternion code, the parts from its STL and 3MF files, the rest of the
layout from ``report.json`` (joint axes and hardware, base frame, densities, bed). Checks:

1. bars: sections of each link perpendicular to its bar at 20 %..80 % of its length (outside
   its bosses); least caliper width >= 6 mm, length / width <= 30;
2. joints (:mod:`printed_joints`): engagement >= 1.5 x the axle diameter in both links, walls
   >= the profile wall, retention (lock nut and hexagonal trap, the rod's or dowel's cap,
   or without a cap the floor of the turning link's blind bore just past the axle's tip);
3. stands (:mod:`printed_stand`): centre of mass inside the plate's footprint with 10 % margin
   over the cycle, nothing below the plate's top; or ``base.mount`` says how it is fixed;
4. printing (:mod:`printed_layout`): support <= 20 % of the downward area, height <= 3 x the
   contact width, inside the bed;
5. collisions (:mod:`printed_collide`): parts without a common joint >= 1 mm apart, and
   links >= 3 x the sum of their deflections the report predicts;
6. a link printed in pieces (:mod:`printed_pieces`): the pieces make up the link, each dowel
   engaged >= 1.5 x its diameter in both pieces, walls and floors >= the profile wall.

``python -m independent.printed_check FOLDER`` (from ``tests/``) prints the JSON findings.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from .meshgeom import RESOLUTION_MM, Sections, section_width
from .printed_collide import check_collisions
from .printed_joints import check_bom, check_joint
from .printed_kin import Export, bars, closure_error, load_export, parameters
from .printed_layout import check_layout
from .printed_pieces import check_pieces
from .printed_stand import check_stand

#: Least bar width (mm) and largest length / width.
MIN_WIDTH_MM = 6.0
MAX_LENGTH_PER_WIDTH = 30.0
#: Gap two links without a common joint keep per the sum of their predicted deflections.
GAP_PER_DEFLECTION = 3.0
#: Stations along each bar (shares of its length).
STATIONS = np.linspace(0.2, 0.8, 25)
#: Largest gap (mm) between a joint axis moved by its two links over the cycle: a micrometre,
#: a hundredth of what a print resolves and 1e5 times below the gap a wrong loop shows
#: (64 - 237 mm); near a singular pose float64 readings of a sound loop part by 1e-4 mm,
#: and on a motion passing very near one (random design 62142, 296 mm, whose motor joint
#: nearly stops) by 1.06e-3 mm: the tolerance grows to CLOSURE_REL of the loop's size (3 um
#: at 300 mm, still 2e4 times below a wrong loop's gap).
CLOSURE_TOL_MM, CLOSURE_REL = 1e-3, 1e-5


def _in_boss(ex: Export, link: int, x: np.ndarray) -> bool:
    """Whether the point ``x`` (mm) lies within 1 mm of one of the link's bosses (a joint's
    cylinder from report.json: ``boss_radius_mm`` around its axis over ``bosses_mm``)."""
    for jt in ex.report["joints"]:
        j = int(jt["joint"])
        if link not in (j, (j + 1) % 6):
            continue
        lo, hi = jt["bosses_mm"][0 if link == j else 1]
        a = np.asarray(jt["axis"], float)
        d = x - np.asarray(jt["origin_mm"], float)
        s = d @ a
        if lo - 1 <= s <= hi + 1 and np.linalg.norm(d - s * a) <= jt["boss_radius_mm"] + 1:
            return True
    return False


def check_bars(ex: Export) -> tuple[list[dict], list[str]]:
    """Least width, its station and length / width of every bar (mm). Stations inside a
    boss (a short link's joints reach past 20 % of it) belong to the joint, not the bar."""
    rows, fails = [], []
    for link, a, b in bars(ex):
        length = float(np.linalg.norm(b - a))
        keep = [x for x in STATIONS if not _in_boss(ex, link, a + x * (b - a))]
        row = {"link": link, "length_mm": length, "stations": len(keep)}
        rows.append(row)
        if not keep:
            row.update(min_width_mm=None, length_per_width=None)
            continue
        sec = Sections(ex.links[link].vertices, ex.links[link].faces, a, b - a,
                       np.array(keep) * length)
        widths = np.array([section_width(sec, k, np.zeros(2))[0] for k in range(len(keep))])
        k = int(np.argmin(widths))
        w = float(widths[k])
        row.update(min_width_mm=w, at_share=float(keep[k]),
                   length_per_width=length / w if w > 0 else float("inf"))
        if w == 0:
            fails.append(f"bar: link {link} has a hole or notch across its axis at "
                         f"{keep[k]:.0%} of its {length:.0f} mm bar (no material around it)")
        elif not w >= MIN_WIDTH_MM + RESOLUTION_MM:
            fails.append(f"bar: link {link} is {w:.2f} mm wide at {keep[k]:.0%} of its "
                         f"{length:.0f} mm bar < {MIN_WIDTH_MM:g} mm")
        if w > 0 and not length <= MAX_LENGTH_PER_WIDTH * (w - RESOLUTION_MM):
            fails.append(f"bar: link {link} length / width {row['length_per_width']:.1f} > "
                         f"{MAX_LENGTH_PER_WIDTH:g}")
    return rows, fails


def check_export(folder: str | Path, collisions: bool = True) -> dict:
    """Findings of an export folder: ``figures`` (JSON-ready), ``failures`` and ``warnings``
    (sentences); ``collisions=False`` leaves out the (slowest) clearance check."""
    ex = load_export(folder)
    figures: dict = {"folder": str(folder), "scale_mm_per_unit": ex.scale}
    fails: list[str] = []
    warns: list[str] = []
    gap = closure_error(ex, parameters(ex.jf, 500))
    figures["closure_mm"] = gap
    size = float(np.max(np.ptp(ex.points_mm, axis=0)))
    if not gap < max(CLOSURE_TOL_MM, CLOSURE_REL * size):
        fails.append(f"result.json: the loop's joint axes part by {gap:.3g} mm over the cycle")
    figures["bars"], f = check_bars(ex)
    fails += f
    wall = float(ex.report["sizing"]["wall_mm"])
    figures["joints"] = []
    for j in range(len(ex.report["joints"])):
        row, f, w = check_joint(ex, j, wall)
        figures["joints"].append(row)
        fails += f
        warns += w
    fails += check_bom(ex.report)
    figures["stand"], f = check_stand(ex)
    fails += f
    figures["print"], f = check_layout(ex)
    fails += f
    figures["pieces"], f = check_pieces(ex, wall)
    fails += f
    if collisions:
        figures["collisions"], f = check_collisions(ex, figures["stand"].get("rod"))
        fails += f + check_bending(ex.report, figures["collisions"]["pairs"])
    return {"figures": _plain(figures), "failures": fails, "warnings": warns}


def check_bending(report: dict, pairs: list[dict]) -> list[str]:
    """Failures where two links without a common joint come closer over the cycle (the
    measured ``pairs`` of :func:`check_collisions`) than 3 x the sum of the deflections the
    report predicts for them (self-weight sag and, where a motor drives it, its torque)."""
    bend = {s["link"]: s["sag_mm"] + (s["torque_deflection_mm"] or 0.0)
            for s in report["stiffness"]["links"]}
    fails = []
    for r in pairs:
        a, b = r["parts"]
        if not (a.startswith("link_") and b.startswith("link_")):
            continue
        need = GAP_PER_DEFLECTION * (bend[int(a[5:])] + bend[int(b[5:])])
        if not r["min_mm"] >= need - RESOLUTION_MM:
            fails.append(f"bending: {a} and {b} come {r['min_mm']:.2f} mm apart, under "
                         f"{GAP_PER_DEFLECTION:g} x their predicted deflections ({need:.2f} mm)")
    return fails


def _plain(x):
    """JSON-ready copy: numpy scalars to Python, non-finite floats to strings."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return _plain(x.tolist())
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not np.isfinite(x):
        return str(x)
    return x


def summary(findings: dict) -> dict:
    """The headline figures of :func:`check_export`'s findings."""
    f = findings["figures"]
    measured = [b for b in f["bars"] if b["min_width_mm"] is not None]
    out = {"min_bar_width_mm": min((b["min_width_mm"] for b in measured), default=None),
           "max_length_per_width": max((float(b["length_per_width"]) for b in measured),
                                       default=None),
           "min_engagement_mm": min(r["engagement_mm"] for j in f["joints"] for r in j["links"]),
           "min_boss_wall_mm": min(float(r["boss_wall_mm"]) for j in f["joints"]
                                   for r in j["links"]),
           "max_support_share": max(p["support_share"] for p in f["print"]["parts"]),
           "max_height_per_width": max(float(p["height_per_width"])
                                       for p in f["print"]["parts"]),
           "failures": len(findings["failures"])}
    if f["stand"].get("stands"):
        out["com_margin_share"] = f["stand"]["com_margin_share"]
    if "collisions" in f:
        out["min_non_adjacent_mm"] = f["collisions"]["min_non_adjacent_mm"]
    return out


if __name__ == "__main__":
    found = check_export(sys.argv[1])
    json.dump(found, sys.stdout, indent=1)
    print()
    sys.exit(1 if found["failures"] else 0)
