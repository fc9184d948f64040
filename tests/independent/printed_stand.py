"""Does the printed sculpture stand? Centre of mass over the cycle against the base's footprint
(independent of paraloop_core).

Masses: every printed part's mesh volume times ``drive.density_kg_m3``; steel hardware
(7.85 g/cm^3) as the cylinders of the joints' pieces; the grounding rod as a cylinder from the
floor of its socket in the plate (a line cast down its axis) to its top. The links move by
:func:`printed_kin.world_motion` (grounded link resting) at >= 2000 parameters over the whole
cycle (t = inf included); the plate, the rod, its cap and the grounded link stay still.
"""

from __future__ import annotations

import numpy as np

from . import joint_profile as jp
from .meshgeom import RESOLUTION_MM, line_hits, point_in_hull
from .printed_kin import parameters, world_motion

#: Steel density, g/mm^3.
STEEL_G_MM3 = 7.85e-3
#: Least distance of the centre of mass inside the footprint, as a share of its diameter.
MARGIN_SHARE = 0.10
#: Table contact: vertices of the plate below this height (mm) make its footprint.
CONTACT_Z_MM = 0.5
#: Parameters sampled over the cycle.
N_SAMPLES = 2000
#: The rod's socket in the plate, in rod diameters (as a joint's engagement).
ROD_SOCKET_FACTOR = 1.5


def _to_world(w: np.ndarray, x: np.ndarray) -> np.ndarray:
    return x @ w[:3, :3].T + w[:3, 3]


def _plate_top(plate, w: np.ndarray) -> float:
    """World height (mm) of the plate's largest upward-facing level (its top face)."""
    up = (plate.face_normals @ w[:3, :3].T)[:, 2] > 0.999
    z = np.round(_to_world(w, plate.triangles_center[up])[:, 2], 2)
    levels, inv = np.unique(z, return_inverse=True)
    return float(levels[np.argmax(np.bincount(inv, weights=plate.area_faces[up]))])


def _rod(ex, w: np.ndarray, plate) -> tuple[dict, list[str], list[tuple[float, np.ndarray]]]:
    """The grounding rod: its ends, socket and mass item ``(grams, centre)`` (home frame)."""
    base = ex.report["base"]
    jt = ex.report["joints"][int(base["rod_joint"])]
    rod = [p for p in jt["pieces"] if p["role"] == "rod"][0]
    o, a = np.asarray(jt["origin_mm"], float), np.asarray(jt["axis"], float)
    up = np.sign((w[:3, :3] @ a)[2])  # +1 when the axis points up in the world
    fails = []
    tilt = float(np.degrees(np.arccos(min(1.0, abs((w[:3, :3] @ a)[2])))))
    if not tilt < 0.5:
        fails.append(f"stand: the rod leans {tilt:.1f} deg from vertical")
    top = o + a * (max(rod["s_mm"]) if up > 0 else min(rod["s_mm"]))
    hits = line_hits(plate.vertices, plate.faces, top, -up * a)
    hits = hits[hits > 0]
    # the socket's floor, or the table under a through hole
    table = _to_world(w, top)[2] / abs((w[:3, :3] @ a)[2])
    bottom = top - up * a * (hits[0] if len(hits) else table)
    length = float(np.linalg.norm(top - bottom))
    r = float(rod["radius_mm"])
    socket = jp.profile(plate, bottom, up * a, -1.0, 40.0)
    in_plate = jp.run_length(jp.held(socket, r))
    if not in_plate >= ROD_SOCKET_FACTOR * 2 * r:
        fails.append(f"stand: the rod sits {in_plate:.1f} mm deep in the plate < "
                     f"{ROD_SOCKET_FACTOR * 2 * r:.1f} mm (1.5 x its diameter)")
    cut = [b for b in ex.report.get("bill_of_materials", []) if "rod" in b["item"]]
    listed = None
    if cut and "cut to" in cut[0]["item"]:
        listed = float(cut[0]["item"].split("cut to")[1].split("mm")[0])
        if not abs(listed - length) <= 1.0:
            fails.append(f"stand: the rod measures {length:.1f} mm from its socket's floor to "
                         f"its top, the bill of materials cuts it to {listed:g} mm")
    info = {"length_mm": length, "in_plate_mm": in_plate, "bom_cut_mm": listed,
            "tilt_deg": tilt, "radius_mm": r, "bottom": bottom.tolist(), "top": top.tolist()}
    return info, fails, [(STEEL_G_MM3 * np.pi * r * r * length, (top + bottom) / 2)]


def _masses(ex, dens: float, plate) -> tuple[list, list, dict, list[str]]:
    """Fixed items ``[(g, home centre)]``, per-link items ``[(link, g, home centre)]``."""
    w = ex.world_from_home()
    fixed, moving = [], []
    for i, m in enumerate(ex.links):
        moving.append((i, m.volume * dens, m.center_mass))
    for jt in ex.report["joints"]:
        o, a = np.asarray(jt["origin_mm"], float), np.asarray(jt["axis"], float)
        for p in jt.get("pieces", []):
            if p.get("printed") or p["role"] == "rod":
                continue
            s0, s1 = p["s_mm"]
            g = STEEL_G_MM3 * np.pi * p["radius_mm"] ** 2 * (s1 - s0)
            moving.append((int(jt["joint"]), g, o + a * (s0 + s1) / 2))  # on the axis
    for part in ex.report.get("parts", []):
        if part["role"] in ("link", "base", "link piece"):  # a piece: in its link's mesh
            continue
        m = ex.mesh(part["name"])
        if part["name"].startswith("rod_cap"):
            # glued on the still rod (report.json's "link" of a rod cap is its joint's index)
            fixed.append((m.volume * dens, m.center_mass))
        else:
            moving.append((int(part["link"]), m.volume * dens, m.center_mass))
    fixed.append((plate.volume * dens, plate.center_mass))
    rod_info, fails = {}, []
    if ex.report["base"].get("rod_joint") is not None:
        rod_info, fails, rod_mass = _rod(ex, w, plate)
        fixed += rod_mass
    g = ex.grounded
    fixed += [(gm, c) for i, gm, c in moving if i == g]
    moving = [(i, gm, c) for i, gm, c in moving if i != g]
    return fixed, moving, rod_info, fails


def check_stand(ex) -> tuple[dict, list[str]]:
    """Figures and failures of the standing check."""
    base = ex.report.get("base") or {}
    if not base.get("stands"):
        mount = base.get("mount") or ex.report.get("mount")  # top level: no base at all
        ok = isinstance(mount, str | dict) and bool(mount)
        return {"stands": False, "mount": mount}, [] if ok else [
            "stand: the loop does not stand and report.json base.mount does not say how it "
            "is fixed"]
    w = ex.world_from_home()
    plate = ex.mesh("base_plate")
    dens = float(ex.report["drive"]["density_kg_m3"]) * 1e-6  # g/mm^3
    fixed, moving, rod_info, fails = _masses(ex, dens, plate)
    pv = _to_world(w, plate.vertices)
    foot = pv[pv[:, 2] < CONTACT_Z_MM][:, :2]
    diameter = float(np.max(np.linalg.norm(foot[:, None] - foot[None], axis=-1)))
    if not abs(pv[:, 2].min()) < 0.05:
        fails.append(f"stand: the plate's underside is at z = {pv[:, 2].min():.2f} mm, "
                     "not on the table")
    t = parameters(ex.jf, N_SAMPLES)
    rot, tr = world_motion(ex, t)  # (T, 6, 3, 3), (T, 6, 3)
    total = sum(g for g, _ in fixed) + sum(g for _, g, _ in moving)
    moment = sum(g * _to_world(w, c) for g, c in fixed) * np.ones((len(t), 3))
    for i, g, c in moving:
        moment = moment + g * (rot[:, i] @ c + tr[:, i])
    com = moment / total
    margin = point_in_hull(foot, com[:, :2])
    k = int(np.argmin(margin))
    step = float(np.max(np.linalg.norm(np.diff(com[:, :2], axis=0), axis=1)))
    top = _plate_top(plate, w)
    lowest = min(float(np.min(np.einsum("tj,vj->tv", rot[:, i, 2], m.vertices) + tr[:, i, 2:3]))
                 for i, m in enumerate(ex.links))
    out = {"stands": True, "samples": len(t), "mass_g": total,
           "footprint_diameter_mm": diameter, "com_margin_mm": float(margin[k]),
           "com_margin_share": float(margin[k] / diameter), "worst_t": float(t[k]),
           "com_step_mm": step, "plate_top_mm": top, "lowest_link_mm": lowest, "rod": rod_info}
    if not margin[k] - step / 2 - RESOLUTION_MM >= MARGIN_SHARE * diameter:
        fails.append(f"stand: the centre of mass comes {margin[k]:.1f} mm inside the "
                     f"footprint's edge (less {step / 2:.1f} mm between samples) < "
                     f"{MARGIN_SHARE:.0%} of its {diameter:.0f} mm diameter")
    if not lowest >= top + RESOLUTION_MM:
        fails.append(f"stand: a link goes down to z = {lowest:.2f} mm, below the plate's top "
                     f"({top:.2f} mm)")
    return out, fails
