"""Print layout and assembly guide written beside the exported parts.

* **Print orientation** (:func:`lay_flat`): a part rests on a plane of its convex hull. The
  candidates are the hull's face normals; the *contact* of one is the area of the part's own
  faces lying in that plane (within :data:`CONTACT_MM`), i.e. what really touches the bed. The
  chosen orientation has the lowest height among those with at least :data:`MIN_CONTACT_MM2`
  of contact (else the largest contact); parts with little contact are flagged for a brim.
  Overhangs (round bars, bosses) need supports: the guide says so, it does not plan them.
* **Bed layout** (:func:`bed_layout`): footprints turned to their smallest 2D bounding box
  (and on, diagonally, where that box does not fit the bed square-on), placed in rows
  (largest first) with :data:`GAP_MM` between them, a new plate when the bed is full.
  Print-in-place parts are captured by their pin heads, so they are one print: the assembly in
  its home pose, standing on its lowest point.
* **Guide** (:func:`guide_files`): ``assembly.md`` (part list with dimensions, which pin goes
  into which bore, order of assembly, print orientation, settings) with one picture per step
  (``assembly_step_<k>.png``: the links' centre lines, new link in colour), and the plates as
  3MF (``paraloop.3mf`` the first, ``paraloop_plate<k>.3mf`` the others).
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np
import trimesh

from paraloop_core.fabrication import sizing
from paraloop_core.fabrication.parts import Assembly

#: A face counts as touching the bed within this height (mm).
CONTACT_MM = 0.05
#: Contact area (mm^2) a part should stand on without a brim.
MIN_CONTACT_MM2 = 25.0
#: Gap between parts on a plate and to the bed's edge (mm).
GAP_MM = 5.0
#: Density of PLA (g / cm^3) for the masses in the part list.
PLA_G_CM3 = 1.24


@dataclass(frozen=True)
class Placement:
    """Where one part is printed: ``plate`` index, ``transform`` ``(4, 4)`` from the part's
    home frame (mm) to the plate (bed corner at the origin, z up), print ``height_mm``,
    ``contact_mm2`` on the bed, its box on the plate from ``corner_mm`` ``(3,)`` over
    ``extent_mm`` ``(3,)``."""

    name: str
    plate: int
    transform: np.ndarray
    height_mm: float
    contact_mm2: float
    corner_mm: np.ndarray
    extent_mm: np.ndarray


def lay_flat(mesh: trimesh.Trimesh) -> tuple[np.ndarray, float, float]:
    """``(rotation (4, 4), height mm, contact mm^2)`` resting ``mesh`` on its best hull plane
    (module docstring); the rotation maps the plane's outward normal to ``-z``."""
    hull = mesh.convex_hull
    normals = np.unique(np.round(hull.face_normals, 6), axis=0)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    support = (mesh.vertices @ normals.T).max(axis=0)  # (K,) the plane n.x = support
    aligned = mesh.face_normals @ normals.T > 1.0 - 1e-6  # (F, K)
    in_plane = np.abs(mesh.triangles_center @ normals.T - support) <= CONTACT_MM
    contact = (mesh.area_faces[:, None] * (aligned & in_plane)).sum(axis=0)
    height = np.ptp(mesh.vertices @ normals.T, axis=0)
    ok = contact >= MIN_CONTACT_MM2
    best = int(np.argmin(np.where(ok, height, np.inf))) if ok.any() else int(np.argmax(contact))
    rot = trimesh.geometry.align_vectors(normals[best], [0.0, 0.0, -1.0])
    return rot, float(height[best]), float(contact[best])


def bed_layout(meshes: dict[str, trimesh.Trimesh], bed_mm: tuple[float, float, float],
               in_place: bool = False) -> list[Placement]:
    """Placements of ``meshes`` (home frame, mm) on plates of the bed ``bed_mm``."""
    if in_place:
        lo = np.min([m.bounds[0] for m in meshes.values()], axis=0)
        move = trimesh.transformations.translation_matrix([GAP_MM - lo[0], GAP_MM - lo[1], -lo[2]])
        ext = np.max([m.bounds[1] for m in meshes.values()], axis=0) - lo
        corner = np.array([GAP_MM, GAP_MM, 0.0])
        return [Placement(n, 0, move, float(ext[2]), 0.0, corner, ext) for n in meshes]
    laid = {}
    for name, mesh in meshes.items():
        rot, height, contact = lay_flat(mesh)
        xy = trimesh.transform_points(mesh.vertices, rot)[:, :2]
        to_box, extents = trimesh.bounds.oriented_bounds_2D(xy)
        turn = np.eye(4)
        turn[:2, :2], turn[:2, 3] = to_box[:2, :2], to_box[:2, 2]
        m = turn @ rot
        box = trimesh.transform_points(mesh.vertices, m)
        room = np.asarray(bed_mm[:2], float) - 2 * GAP_MM
        if np.any(np.ptp(box[:, :2], axis=0) > room):  # turned (diagonal) if that fits
            _, angle = sizing.footprint_turn(np.ptp(box[:, :2], axis=0), room)
            m = trimesh.transformations.rotation_matrix(float(angle), [0, 0, 1]) @ m
            box = trimesh.transform_points(mesh.vertices, m)
        m = trimesh.transformations.translation_matrix(-box.min(axis=0)) @ m
        laid[name] = (m, np.ptp(box, axis=0), height, contact)
    out, plate, x, y, row = [], 0, GAP_MM, GAP_MM, 0.0
    for name in sorted(laid, key=lambda n: -laid[n][1][1]):  # deepest first: even rows
        m, size, height, contact = laid[name]
        if x + size[0] > bed_mm[0] - GAP_MM and x > GAP_MM:  # next row
            x, y, row = GAP_MM, y + row + GAP_MM, 0.0
        if y + size[1] > bed_mm[1] - GAP_MM and y > GAP_MM:  # next plate
            plate, x, y, row = plate + 1, GAP_MM, GAP_MM, 0.0
        out.append(Placement(name, plate, trimesh.transformations.translation_matrix(
            [x, y, 0.0]) @ m, height, contact, np.array([x, y, 0.0]), size))
        x, row = x + size[0] + GAP_MM, max(row, size[1])
    return sorted(out, key=lambda p: p.name)


def plate_files(meshes: dict[str, trimesh.Trimesh], layout: list[Placement]
                ) -> list[tuple[str, bytes]]:
    """One 3MF per plate with the parts (named) in print orientation."""
    files = []
    for plate in sorted({p.plate for p in layout}):
        scene = trimesh.Scene()
        for p in layout:
            if p.plate == plate:
                scene.add_geometry(meshes[p.name].copy().apply_transform(p.transform),
                                   node_name=p.name, geom_name=p.name)
        name = "paraloop.3mf" if plate == 0 else f"paraloop_plate{plate + 1}.3mf"
        files.append((name, scene.export(file_type="3mf")))
    return files


def _joint_text(i: int) -> str:
    return f"joint {i} (axis A_{i}): the pin of link_{i} goes into the bore of link_{(i + 1) % 6}"


def _step_picture(asm: Assembly, upto: int, joint: int | None, title: str) -> bytes:
    """PNG: links ``0..upto`` at home as their capsule centre lines (new one in colour), the
    joint being assembled as a dashed axis line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(4.0, 4.0), dpi=90)
    ax = fig.add_subplot(projection="3d")
    every = np.concatenate([p.capsules.reshape(-1, 3) for p in asm.parts])
    for p in asm.parts[: upto + 1]:
        colour = f"C{p.link}" if p.link == upto else "0.6"
        for seg, r in zip(p.capsules, p.radii, strict=True):
            ax.plot(*seg.T, color=colour, linewidth=max(1.0, min(8.0, r)), solid_capstyle="round")
    if joint is not None:
        z = asm.zones[joint]
        line = np.stack([z.at(z.s0 - 0.5 * z.length), z.at(z.s1 + 0.5 * z.length)])
        ax.plot(*line.T, "k--", linewidth=1.0)
    lo, hi = every.min(axis=0), every.max(axis=0)
    mid, half = (lo + hi) / 2, (hi - lo).max() / 2
    for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), mid, strict=True):
        setter(c - half, c + half)
    ax.set_axis_off()
    ax.set_title(title, fontsize=9)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", bbox_inches="tight")
    plt.close(fig)
    return buf.getvalue()


def layout_entry(layout: list[Placement], bed_mm: tuple[float, float, float]) -> dict:
    """The ``print_layout`` report entry: plates, and per part its plate, height, contact,
    transform and whether it fits the bed."""
    parts = []
    for p in layout:
        far = p.corner_mm + p.extent_mm
        parts.append({"name": p.name, "plate": p.plate + 1, "height_mm": p.height_mm,
                      "contact_mm2": p.contact_mm2, "transform": p.transform.tolist(),
                      "fits_bed": bool(np.all(far <= np.asarray(bed_mm) + 1e-9))})
    return {"bed_mm": list(bed_mm), "plates": 1 + max(p.plate for p in layout), "parts": parts}


def guide_pages(asm: Assembly, meshes: dict[str, trimesh.Trimesh], layout: list[Placement],
                bed_mm: tuple[float, float, float], settings: dict | None = None
                ) -> list[tuple[str, bytes]]:
    """``assembly.md`` and its pictures for the parts ``meshes`` printed as ``layout``;
    ``settings``: extra lines for the print settings (e.g. the printer profile)."""
    spec = asm.spec
    rows = []
    for p in layout:
        m = meshes[p.name]
        ext = np.sort(m.bounding_box_oriented.primitive.extents)[::-1]
        rows.append(f"| {p.name}.stl | {ext[0]:.1f} x {ext[1]:.1f} x {ext[2]:.1f} | "
                    f"{m.volume / 1e3:.1f} | {m.volume / 1e3 * PLA_G_CM3:.0f} | {p.plate + 1} | "
                    f"{p.height_mm:.1f} | {p.contact_mm2:.0f}"
                    f"{'' if p.contact_mm2 >= MIN_CONTACT_MM2 else ' (use a brim)'} |")
    lines = ["# Assembly guide", "",
             "Six printed links form a closed 6R loop that turns inside out (paraloop).", "",
             "## Parts", "",
             "| file | size (mm) | volume (cm^3) | PLA (g) | plate | print height (mm) | "
             "contact (mm^2) |", "|---|---|---|---|---|---|---|", *rows, "",
             "Each `link_<i>.stl` is link i in the assembled home pose (base frame, mm), so the "
             "files drop into CAD assembled; the 3MF plates hold the same parts laid on a flat "
             "face for printing.", "",
             "## Joints", "", f"Pin radius {spec.pin_radius_mm:.2f} mm, bore radius "
             f"{spec.pin_radius_mm + spec.clearance_mm:.2f} mm (clearance "
             f"{spec.clearance_mm:.2f} mm), boss radius {spec.boss_radius_mm:.2f} mm.", "",
             *[f"- {_joint_text(i)}" for i in range(6)], ""]
    pictures = []
    if spec.print_in_place:
        lines += ["## Assembly", "", "Print-in-place: the pin heads capture the links, so the "
                  "loop prints as one job (`paraloop.3mf`, the home pose). After printing, turn "
                  "each joint gently until it moves freely.", ""]
    else:
        lines += ["## Assembly", ""]
        for k in range(7):
            upto, joint = min(k, 5), (None if k == 0 else k - 1 if k < 6 else 5)
            text = ("Lay link_0 down (with its grounding column, if any)." if k == 0 else
                    f"Slide the bore of link_{k} onto the pin of link_{k - 1} (joint {k - 1}, "
                    f"axis A_{k - 1})."
                    if k < 6 else "Close the loop: turn the joints until the pin of link_5 lines "
                    "up with the bore of link_0 (the pose of `assembly.glb`) and slide it in.")
            name = f"assembly_step_{k + 1}.png"
            title = "close the loop" if k == 6 else f"step {k + 1}"
            pictures.append((name, _step_picture(asm, upto, joint, title)))
            lines += [f"{k + 1}. {text}", "", f"   ![step {k + 1}]({name})", ""]
        lines += ["The pins are not captured: they slide in their bores. Secure each pin end "
                  "(a washer glued to the pin tip, not to the bore) or export with "
                  "`--print-in-place`. Then turn the loop through its whole cycle by hand.", ""]
    extra = "".join(f"- {k}: {v}\n" for k, v in (settings or {}).items())
    lines += ["## Print settings", "",
              f"- bed: {' x '.join(f'{v:g}' for v in bed_mm)} mm; parts on "
              f"{1 + max(p.plate for p in layout)} plate(s)",
              f"- layer height <= {min(0.2, spec.clearance_mm / 1.5):.2f} mm (the joint "
              "clearance needs at least 1.5 layers)",
              "- supports: on (round bars and bosses overhang); PLA or PETG, >= 3 perimeters",
              extra.rstrip("\n"), ""]
    return pictures + [("assembly.md", "\n".join(lines).encode())]
