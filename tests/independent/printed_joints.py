"""Joint checks of a printed export, measured on the link meshes (independent of paraloop_core).

For joint j (``report.json`` ``joints[j]``: origin, axis from E_j towards S_{j+1}, boss ranges,
kind, axle diameter, hardware ``pieces`` with axial ranges) the two links' profiles around the
axis (:mod:`joint_profile`) give: the bore actually present, the length over which the axle is
held (material at every angle, bore <= axle + 0.5 mm), the walls around it, pieces that would
not fit, and for screw joints the retention (a lock nut, in a hexagonal trap that takes it
and stops it turning or outside its boss on a washer, head and nut bearing on material, the
stock screw reaching past the nut); rod and dowel joints need their printed cap.
"""

from __future__ import annotations

import re

import numpy as np

from . import joint_profile as jp
from .meshgeom import RESOLUTION_MM

#: Engagement of an axle in each link, in axle diameters (issue 26).
ENGAGE_FACTOR = 1.5
#: Thread pitch as a share of the nominal diameter (M3 0.5 mm, M4 0.7 mm: 0.167, 0.175);
#: a lock nut's insert grips only when the screw passes its far face by about a pitch.
PITCH_SHARE = 0.16
#: Least length (mm) of the rod inside its printed cap.
ROD_IN_CAP_MM = 2.0
#: Farthest (mm) a capless rod's blind floor may stand past the rod's tip: the printer's
#: clearance and a station of the profile, with room to spare; farther, the link slides.
TIP_PLAY_MM = 1.0
#: How far past the bosses the profiles are measured (mm).
SCAN_MARGIN_MM = 3.0


def _pieces(joint: dict, role: str) -> list[dict]:
    return [p for p in joint.get("pieces", []) if role in p["role"]]


def _free_radius(piece: dict) -> float:
    """Radius a piece needs free around the axis: the circle, or a hexagon's flats."""
    r = float(piece["radius_mm"])
    return r * np.cos(np.pi / 6) if int(piece.get("sides", 0)) == 6 else r


def check_joint(ex, j: int, wall_mm: float) -> tuple[dict, list[str], list[str]]:
    """Figures, failures and warnings (words) of joint ``j`` of the export ``ex``."""
    jt = ex.report["joints"][j]
    origin, axis = np.asarray(jt["origin_mm"], float), np.asarray(jt["axis"], float)
    axis = axis / np.linalg.norm(axis)
    fails: list[str] = []
    warns: list[str] = []
    # the joint must sit on the realization's axis E_j -> S_{j+1}
    e, s = ex.points_mm[2 * j + 1], ex.points_mm[(2 * j + 2) % 12]
    off = np.linalg.norm(np.cross(origin - e, (s - e) / np.linalg.norm(s - e)))
    if not off < 1e-6 * max(1.0, np.abs(ex.points_mm).max()):
        fails.append(f"joint {j}: report origin {off:.3g} mm off the result's axis E{j}S{j + 1}")
    r_axle = float(jt["axle_diameter_mm"]) / 2
    bosses = np.asarray(jt["bosses_mm"], float)
    ext = [p["s_mm"] for p in jt.get("pieces", [])] + bosses.tolist()
    lo, hi = min(x[0] for x in ext) - SCAN_MARGIN_MM, max(x[1] for x in ext) + SCAN_MARGIN_MM
    prof = [jp.profile(ex.links[(j + k) % 6], origin, axis, lo, hi) for k in (0, 1)]
    rows = []
    for k, p in enumerate(prof):
        link = (j + k) % 6
        held = jp.held(p, r_axle)
        with np.errstate(invalid="ignore"):  # inf - inf where a ray meets nothing
            walled = held & (np.min(p.rout - p.rin, axis=1) >= wall_mm + RESOLUTION_MM)
        in_boss = (p.s >= bosses[k][0]) & (p.s <= bosses[k][1])
        sur = jp.surrounded(p)
        boss_wall, at_s, at_deg = jp.thinnest_wall(p, sur & in_boss)
        row = {"link": link, "engagement_mm": jp.run_length(walled),
               "held_mm": jp.run_length(held),
               "bore_mm": [float(p.rin[held].min()), float(p.rin[held].max())]
               if held.any() else None,
               "boss_wall_mm": boss_wall, "boss_wall_at": {"s_mm": at_s, "deg": at_deg},
               "sliver_wall_mm": jp.thinnest_wall(p, sur & ~in_boss)[0],
               "floor_mm": jp.floor(p, in_boss)}
        need = ENGAGE_FACTOR * 2 * r_axle
        if not row["engagement_mm"] >= need:
            fails.append(f"joint {j}: link {link} holds the {2 * r_axle:g} mm axle with a "
                         f"{wall_mm:g} mm wall over {row['engagement_mm']:.2f} mm < "
                         f"{need:.2f} mm (1.5 x diameter)")
        if not boss_wall >= wall_mm + RESOLUTION_MM:
            fails.append(f"joint {j}: link {link} wall {boss_wall:.2f} mm in its boss (around the "
                         f"bore or a recess, at s = {at_s:.1f} mm) < profile wall {wall_mm:g} mm")
        if row["sliver_wall_mm"] < wall_mm:
            warns.append(f"joint {j}: link {link} has walls of {row['sliver_wall_mm']:.2f} mm "
                         "around the bore outside its boss (a bar's end cut by the bore)")
        if row["floor_mm"] is not None and not row["floor_mm"] >= wall_mm + RESOLUTION_MM:
            fails.append(f"joint {j}: link {link} floor of {row['floor_mm']:.2f} mm under its "
                         f"blind bore < profile wall {wall_mm:g} mm")
        for piece in jt.get("pieces", []):
            if piece.get("printed"):
                continue
            bad = jp.intrusion(p, *piece["s_mm"], _free_radius(piece))
            if bad > 0:
                fails.append(f"joint {j}: link {link} material inside the {piece['role']} "
                             f"over {bad:.1f} mm (it cannot be fitted)")
        rows.append(row)
    out = {"joint": j, "kind": jt["kind"], "axle_diameter_mm": 2 * r_axle, "links": rows}
    if _pieces(jt, "lock nut"):
        fails += _screw_retention(ex, jt, prof, out)
    elif jt["kind"] in ("rod", "dowel"):
        fails += _rod_retention(ex, jt, prof, origin, axis, out, wall_mm)
    elif not any(p.get("printed") and re.search("cap|clip|retainer", p["role"])
                 for p in jt.get("pieces", [])):
        fails.append(f"joint {j}: nothing retains the {jt['kind']} axle (no lock nut, cap, "
                     "clip or retainer among its pieces)")
    return out, fails, warns


def _screw_retention(ex, jt: dict, prof: list, out: dict) -> list[str]:
    """A screw and lock nut: the nut's trap (or its washer outside the boss), the head's and
    nut's bearing faces, the reach."""
    j, fails = jt["joint"], []
    head, nut = _pieces(jt, "screw head")[0], _pieces(jt, "lock nut")[0]
    h0, h1 = head["s_mm"]
    n0, n1 = nut["s_mm"]
    toward = 1 if (n0 + n1) > (h0 + h1) else -1  # from the head to the nut along the axis
    mids = [np.mean(r) for r in jt["bosses_mm"]]
    k_nut = int(np.argmin([abs(m - (n0 + n1) / 2) for m in mids]))
    k_head = 1 - k_nut
    a_nut = 2 * _free_radius(nut)
    lo, hi = jt["bosses_mm"][k_nut]
    trapped = lo < (n0 + n1) / 2 < hi  # sunk in its boss, else outside on a washer
    clear, blocked = jp.hex_fit(prof[k_nut], n0, n1, a_nut) if trapped else (None, None)

    def washer(a: float, b: float) -> dict | None:
        """The washer (not the thrust washer) filling the axial gap [a, b] (a face station
        lies up to a step inside the material), if any."""
        tol = jp.STEP_MM + 0.05
        return next((w for w in _pieces(jt, "washer") if "thrust" not in w["role"] and
                     min(w["s_mm"]) <= min(a, b) + tol and max(w["s_mm"]) >= max(a, b) - tol),
                    None)

    def face(k: int, piece_r: float, start: float, direction: int) -> float | None:
        """The face a head or nut bears on (through its washer: the washer's radius)."""
        f = jp.bearing_face(prof[k], piece_r - jp.FIT_TOL_MM, start, direction)
        if f is None or trapped and k == k_nut:
            return f
        w = washer(start, f)
        if abs(f - start) > 2 * jp.STEP_MM and w is None:
            return None  # a gap with nothing in it: the head or nut does not bear on the link
        return f

    head_face = face(k_head, float(head["radius_mm"]), h1 if toward > 0 else h0, toward)
    nut_face = face(k_nut, a_nut / 2, n0 if toward > 0 else n1, -toward)
    screw_len = float(jt["screw_length_mm"])
    pitch = PITCH_SHARE * out["axle_diameter_mm"]
    height = n1 - n0
    reach = None
    if head_face is not None and nut_face is not None:
        # conservative: the head's face may be one step nearer the nut, the nut's one step
        # farther than the stations found
        reach = toward * (head_face - nut_face) + screw_len - height - 2 * jp.STEP_MM
    out["retention"] = {"nut_link": out["links"][k_nut]["link"],
                        "trap_clearance_mm": clear, "trap_blocks_turning_share": blocked,
                        "head_face_mm": head_face, "nut_face_mm": nut_face,
                        "screw_length_mm": screw_len, "past_nut_mm": reach}
    nut_link = out["links"][k_nut]["link"]
    if nut_link != (j + 1) % 6:
        fails.append(f"joint {j}: the nut sits in link {nut_link}, not link {(j + 1) % 6}")
    if trapped and not clear >= RESOLUTION_MM - jp.FIT_TOL_MM:
        fails.append(f"joint {j}: the {a_nut:.2f} mm nut does not fit its trap "
                     f"(short by {-clear:.2f} mm)")
    if trapped and not blocked >= 0.5:
        fails.append(f"joint {j}: the trap stops the nut turning over only {blocked:.0%} "
                     "of its height (not hexagonal)")
    if head_face is None:
        fails.append(f"joint {j}: no face in link {out['links'][k_head]['link']} for the "
                     "screw head to bear on")
    if nut_face is None:
        fails.append(f"joint {j}: no face in link {nut_link} for the nut to bear on")
    if reach is not None and not reach >= pitch + RESOLUTION_MM:
        fails.append(f"joint {j}: the {screw_len:g} mm screw passes the nut's far face by "
                     f"{reach:.2f} mm < {pitch:.2f} mm (a thread)")
    return fails


def _rod_retention(ex, jt: dict, prof: list, origin, axis, out: dict, wall_mm: float
                   ) -> list[str]:
    """A rod joint: the rod is held by the grounded link (a dowel joint: by the link the report
    names ``fixed_link``, in a blind bore); a printed cap on the axle's end keeps the other
    link on, bearing over its bore."""
    j, fails, kind = jt["joint"], [], jt["kind"]
    caps = _pieces(jt, "cap")
    rods = _pieces(jt, kind)
    name = f"{kind}_cap_{j}"
    if not caps:
        return _blind_retention(ex, jt, prof, out, wall_mm)
    if not caps or not (ex.folder / f"{name}.stl").exists():
        return [f"joint {j}: {kind} joint without its printed cap ({name}.stl)"]
    cap, rod = caps[0], [p for p in rods if p["role"] == kind][0]
    holder = ex.grounded if kind == "rod" else jt.get("fixed_link")
    r_rod = float(rod["radius_mm"])
    c0, c1 = cap["s_mm"]
    p = jp.profile(ex.mesh(name), origin, axis, c0 - 1, c1 + 1)
    in_cap = jp.run_length(jp.held(p, r_rod))
    # the cap's own walls: around the axle's end and over it (a floor to its blind hole)
    cap_wall = jp.thinnest_wall(p, jp.held(p, r_rod))[0]
    cap_floor = jp.floor(p, np.ones(len(p.s), bool))
    ends = np.asarray(jt["bosses_mm"], float)
    turning = 0 if holder == (j + 1) % 6 else 1
    bore = out["links"][turning]["bore_mm"]
    bore_r = bore[1] if bore else r_rod
    # the cap's face toward the turning link must cover that link's bore with material
    toward = -1 if c0 >= ends[turning][1] - 1e-9 else 1
    face = p.near(c0 + 0.15 if toward < 0 else c1 - 0.15)
    covers = bool(np.all(p.rin[face] <= bore_r) and np.all(p.rout[face] >= bore_r + 1.0))
    out["retention"] = {"cap": name, "rod_in_cap_mm": in_cap, "cap_covers_bore": covers,
                        "cap_wall_mm": cap_wall, "cap_floor_mm": cap_floor,
                        "turning_link": out["links"][turning]["link"]}
    if not cap_wall >= wall_mm + RESOLUTION_MM or not (
            cap_floor is None or cap_floor >= wall_mm + RESOLUTION_MM):
        fails.append(f"joint {j}: the cap {name} has walls of {cap_wall:.2f} mm and a floor of "
                     f"{cap_floor or 0:.2f} mm over the {kind}'s end < profile wall "
                     f"{wall_mm:g} mm")
    if holder not in (j, (j + 1) % 6):
        fails.append(f"joint {j}: the {kind} joint is not a joint of the link holding it")
    if not in_cap >= ROD_IN_CAP_MM:
        fails.append(f"joint {j}: the {kind} reaches {in_cap:.2f} mm into its cap "
                     f"< {ROD_IN_CAP_MM:g} mm")
    if not covers:
        fails.append(f"joint {j}: the cap does not cover link {out['links'][turning]['link']}'s "
                     f"bore (the link can slide off the {kind})")
    return fails


def _blind_retention(ex, jt: dict, prof: list, out: dict, wall_mm: float) -> list[str]:
    """A grounding rod or dowel without a cap: the turning link's bore must be blind, its
    floor (at least a wall thick, on the axis) at most :data:`TIP_PLAY_MM` past the axle's
    tip, so the link cannot slide off its end (the holding link's boss stops it the other
    way). The holder: the grounded link for a rod, ``fixed_link`` for a dowel."""
    j, kind = jt["joint"], jt["kind"]
    holder = ex.grounded if kind == "rod" else jt.get("fixed_link")
    if holder not in (j, (j + 1) % 6):
        return [f"joint {j}: the {kind} joint is not a joint of the link holding it"]
    turning = 0 if holder == (j + 1) % 6 else 1
    rod = [p for p in _pieces(jt, kind) if p["role"] == kind][0]
    s0, s1 = rod["s_mm"]
    p = prof[turning]
    tip, sign = (s1, 1.0) if turning == 1 else (s0, -1.0)  # the rod ends inside that link
    beyond = sign * (p.s - tip)
    solid = p.inside & (beyond > 0)
    first = float(beyond[solid].min()) if solid.any() else np.inf
    start = int(np.flatnonzero(solid & (beyond == first))[0]) if solid.any() else -1
    runs = [(a, b) for a, b in jp.runs_of(p.inside) if a <= start <= b]
    floor = (runs[0][1] - runs[0][0]) * jp.STEP_MM if runs else 0.0  # a lower bound
    out["retention"] = {"blind_floor_mm": floor, "floor_past_tip_mm": first,
                        "turning_link": out["links"][turning]["link"]}
    if not first <= TIP_PLAY_MM or not floor >= wall_mm + RESOLUTION_MM:
        return [f"joint {j}: {kind} joint without its printed cap and without a blind bore in "
                f"link {out['links'][turning]['link']} past its tip (floor {floor:.2f} mm, "
                f"{first:.2f} mm past the tip): the link can slide off the {kind}"]
    return []


def check_bom(report: dict) -> list[str]:
    """Lock nuts and screws of the bill of materials against the joints' hardware."""
    fails = []
    bom = report.get("bill_of_materials", [])
    joints = [jt for jt in report["joints"] if _pieces(jt, "lock nut")]
    nuts = sum(int(b["quantity"]) for b in bom if "lock nut" in b["item"].lower())
    if nuts < len(joints):
        fails.append(f"bill of materials: {nuts} lock nuts for {len(joints)} screw joints")
    for length in sorted({float(jt["screw_length_mm"]) for jt in joints}):
        want = sum(1 for jt in joints if float(jt["screw_length_mm"]) == length)
        have = sum(int(b["quantity"]) for b in bom
                   if re.search(rf"\bx {length:g} mm\b", b["item"]) and "screw" in b["item"])
        if have < want:
            fails.append(f"bill of materials: {have} screws of {length:g} mm for {want} joints")
    return fails
