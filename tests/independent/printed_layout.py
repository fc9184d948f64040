"""Print checks of an export's 3MF plates, read with trimesh (independent of paraloop_core).

Each plate file (``paraloop.3mf``, ``paraloop_plate<k>.3mf``) holds parts in print
orientation, the bed at z = 0 (a link printed in pieces: the pieces, not the link). Per part:
the downward-facing area (faces whose normal points down, n_z < -1e-6), the area needing
support (faces leaning less than 45 deg from straight down, their part more than 0.3 mm
above the bed, cut exactly at that height), its height and the least caliper width of the
convex hull of the faces lying on the bed (z <= 0.05 mm).
"""

from __future__ import annotations

import re

import manifold3d as m3
import numpy as np
import trimesh

from .meshgeom import RESOLUTION_MM, area_above, least_width

#: Overhang limit: faces leaning less than this from straight down need support.
OVERHANG_DEG = 45.0
#: Faces lower than this (mm) rest on the first layer.
FIRST_LAYER_MM = 0.3
#: Largest support area as a share of the downward-facing area.
MAX_SUPPORT_SHARE = 0.20
#: Largest height over the width of what a part stands on.
MAX_HEIGHT_PER_WIDTH = 3.0
#: A face lies on the bed when all its corners are this low (mm).
ON_BED_MM = 0.05
#: Least gap between two parts on one plate (mm), so they print apart.
PART_GAP_MM = 1.0


def plate_files(folder) -> list:
    """The 3MF plates of an export folder, in plate order."""
    def order(p):
        m = re.search(r"plate(\d+)", p.stem)
        return int(m.group(1)) if m else 1
    return sorted(folder.glob("paraloop*.3mf"), key=order)


def _parts(path) -> list[tuple[str, trimesh.Trimesh]]:
    """``(name, mesh)`` of each part of a 3MF file, placed by the scene's transforms."""
    scene = trimesh.load(path)
    out = []
    for node in scene.graph.nodes_geometry:
        transform, name = scene.graph[node]
        mesh = scene.geometry[name].copy()
        mesh.apply_transform(transform)
        out.append((name, mesh))
    return out


def part_figures(mesh: trimesh.Trimesh) -> dict:
    """Support, contact and height figures of one part in print orientation."""
    nz = mesh.face_normals[:, 2]
    area = mesh.area_faces
    tri_z = mesh.triangles[:, :, 2] - mesh.bounds[0, 2]
    down = nz < -1e-6
    steep = nz < -np.cos(np.radians(OVERHANG_DEG))
    support = float(area_above(tri_z[steep], area[steep], FIRST_LAYER_MM).sum())
    flat = np.all(tri_z <= ON_BED_MM, axis=1)
    contact = mesh.triangles[flat][:, :, :2].reshape(-1, 2)
    width = least_width(contact) if len(contact) else 0.0
    height = float(np.ptp(mesh.vertices[:, 2]))
    downward = float(area[down].sum())
    return {"downward_mm2": downward, "support_mm2": support,
            "support_share": support / downward if downward > 0 else 0.0,
            "contact_mm2": float(area[flat].sum()), "contact_width_mm": width,
            "height_mm": height, "height_per_width": height / width if width > 0 else np.inf,
            "bounds_mm": mesh.bounds.tolist(), "volume_mm3": float(mesh.volume)}


def check_layout(ex) -> tuple[dict, list[str]]:
    """Figures per part and failures of the export's plates."""
    bed = np.asarray(ex.report["sizing"]["bed_mm"], float)
    fails, rows = [], []
    seen: dict[str, int] = {}
    for k, path in enumerate(plate_files(ex.folder), start=1):
        parts = _parts(path)
        solids = []
        for name, mesh in parts:
            f = part_figures(mesh)
            f.update(name=name, plate=k)
            rows.append(f)
            seen[name] = seen.get(name, 0) + 1
            lo, hi = np.asarray(f["bounds_mm"])
            if not (np.all(lo[:2] >= 0) and np.all(hi <= bed)):
                fails.append(f"print: {name} on plate {k} leaves the {bed[0]:g} x {bed[1]:g} x "
                             f"{bed[2]:g} mm bed (bounds {np.round(lo, 1)} - {np.round(hi, 1)})")
            if not abs(lo[2]) <= ON_BED_MM:
                fails.append(f"print: {name} on plate {k} starts at z = {lo[2]:.2f} mm, not on "
                             "the bed")
            if not f["support_share"] <= MAX_SUPPORT_SHARE * (1 - 1e-9):
                fails.append(f"print: {name} needs support under {f['support_share']:.0%} of its "
                             f"downward-facing area > {MAX_SUPPORT_SHARE:.0%}")
            if not f["height_mm"] + RESOLUTION_MM <= MAX_HEIGHT_PER_WIDTH * (
                    f["contact_width_mm"] - RESOLUTION_MM):
                fails.append(f"print: {name} stands {f['height_mm']:.1f} mm tall on "
                             f"{f['contact_width_mm']:.1f} mm > {MAX_HEIGHT_PER_WIDTH:g} x")
            solids.append(m3.Manifold(m3.Mesh(
                vert_properties=np.asarray(mesh.vertices, np.float32),
                tri_verts=np.asarray(mesh.faces, np.uint32))))
        for a in range(len(parts)):
            for b in range(a + 1, len(parts)):
                gap = solids[a].min_gap(solids[b], 2 * PART_GAP_MM)
                if not gap >= PART_GAP_MM + RESOLUTION_MM:
                    fails.append(f"print: {parts[a][0]} and {parts[b][0]} on plate {k} are "
                                 f"{gap:.2f} mm apart < {PART_GAP_MM:g} mm")
    for part in ex.report.get("parts", []):
        name = part["name"]
        if part.get("printed_as"):  # its pieces are printed (:mod:`printed_pieces`)
            if name in seen:
                fails.append(f"print: {name} is on a plate beside its pieces")
            continue
        if seen.get(name, 0) != 1:
            fails.append(f"print: {name} is on {seen.get(name, 0)} plates (should be one)")
            continue
        vol = ex.mesh(name).volume
        row = next(r for r in rows if r["name"] == name)
        if not abs(row["volume_mm3"] - vol) <= 1e-3 * vol:
            fails.append(f"print: {name} in the 3MF ({row['volume_mm3']:.0f} mm^3) is not its STL "
                         f"({vol:.0f} mm^3)")
    extra = sorted(set(seen) - {p["name"] for p in ex.report.get("parts", [])})
    if extra:
        fails.append(f"print: parts on the plates not in report.json's parts: {extra}")
    return {"parts": rows}, fails
