"""The export folder's files: parts, plates, assembly, report, bill of materials.

* ``<part>.stl``: every printed part in the assembled home pose (mm, the grounded sculpture's
  frame, z up), so the files drop into CAD assembled: ``link_<i>``, printed pins and caps,
  ``base_plate``;
* an end link printed in pieces (:mod:`split`): ``link_3.stl`` assembled and its pieces
  ``link_3_arm_1``, ``link_3_arm_2``, ``link_3_end`` (the 3MF holds the pieces);
* ``paraloop.3mf`` (``paraloop_plate<k>.3mf`` for more plates): the same parts laid on their
  print faces and arranged on the printer's bed (:mod:`layout`);
* ``assembly.glb``: the assembled loop, parts coloured per link, hardware in steel grey;
* ``parts.step``: every printed part as one solid in the same home pose, exact (cylinders,
  cones, hexagonal prisms, planes, the fillets' oblique cones) where its :mod:`csg` tree has
  no mesh in it, else faceted (an end-effector, a carved body); ``assembly.step``: those
  parts and the metal hardware, named and coloured (:mod:`step`; written last, by
  :func:`step_files`);
* ``report.json``: what the program chose and measured (:mod:`printable`), the print layout
  with each part's support, the parts list and the bill of materials.
"""

from __future__ import annotations

import json
from collections import Counter

import numpy as np
import trimesh

from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import check, layout, profiles, split
from paraloop_core.fabrication.assembly import Assembly
from paraloop_core.fabrication.step_job import StepJob

#: RGB of links 0..5 (and the base, index 6) in the exported assembly and the pictures.
LINK_COLORS = np.array([[150, 150, 150], [220, 60, 60], [60, 160, 70], [240, 140, 30],
                        [60, 110, 220], [170, 80, 200], [120, 110, 100]], np.uint8)
STEEL = np.array([190, 195, 200], np.uint8)


def part_meshes(asm: Assembly) -> dict[str, trimesh.Trimesh]:
    """Every printed part as a trimesh (mm, home pose); raises :class:`FabricationError`
    (``not-watertight``) for a part a slicer would not read as closed."""
    out = {}
    for p in asm.parts:
        tm = check.part_trimesh(p.manifold)
        if not tm.is_watertight:
            raise FabricationError(f"{p.name} is not watertight", "not-watertight")
        out[p.name] = tm
    return out


def downs(asm: Assembly) -> dict[str, np.ndarray]:
    """Each part's print face (home frame): a link's flat, a pin lying on its side, a cap on
    its end, the plate on its underside."""
    out = {}
    for p in asm.parts:
        d = np.asarray(p.down, float)
        if p.role == "pin":  # on its side: layers along the pin
            d = np.cross(d, [1.0, 0, 0] if abs(d[0]) < 0.9 else [0, 1.0, 0])
        out[p.name] = d / np.linalg.norm(d) if np.linalg.norm(d) > 0 else np.array([0, 0, -1.0])
    return out


def color_of(link: int) -> np.ndarray:
    return LINK_COLORS[link if 0 <= link < 6 else 6]


def assembly_glb(asm: Assembly, meshes: dict[str, trimesh.Trimesh]) -> bytes:
    """The assembled loop as binary glTF: parts in their link's colour (the base in brown
    grey), hardware steel grey."""
    scene = trimesh.Scene()
    for p in asm.parts:
        tm = meshes[p.name].copy()
        tm.visual.face_colors = np.append(color_of(-1 if p.role == "base" else p.link), 255)
        scene.add_geometry(tm, node_name=p.name, geom_name=p.name)
    for k, h in enumerate(asm.hardware):
        tm = check.part_trimesh(h.solid)
        tm.visual.face_colors = np.append(STEEL, 255)
        name = f"{h.role.replace(' ', '_')}_{h.joint}_{k}"
        scene.add_geometry(tm, node_name=name, geom_name=name)
    return scene.export(file_type="glb")


def bill_of_materials(asm: Assembly, material: profiles.Material,
                      pieces: split.Split | None = None) -> list[dict]:
    """Hardware and printed parts to buy or print: item, quantity, what for (a link printed
    in ``pieces``: its dowel pins and pieces)."""
    hw: Counter = Counter()
    for j in asm.joints:
        if j.kind in profiles.FASTENERS:
            f = profiles.FASTENERS[j.kind]
            hw[f"{f.name} x {j.screw_mm:g} mm socket head cap screw (ISO 4762)"] += 1
            hw[f"{f.name} nylon-insert lock nut (DIN 985)"] += 1
            hw[f"{f.name} washer (ISO 7089, {f.washer_d_mm:g} x {f.washer_t_mm:g} mm)"] += 3
        elif j.kind == "dowel":
            hw[f"{j.axle_d:g} mm steel dowel pin (ISO 8734) or rod, "
               f"{j.axle.s1 - j.axle.s0:.0f} mm long"] += 1
    rows = [{"item": k, "quantity": v, "for": "joints"} for k, v in sorted(hw.items())]
    if pieces is not None:
        rows.append({"item": f"{split.DOWEL_D_MM:g} mm steel dowel pin (ISO 8734), "
                             f"{split.DOWEL_L_MM:g} mm long", "quantity": len(pieces.dowels),
                     "for": f"gluing link {pieces.link}'s pieces together"})
    for h in asm.hardware:
        if h.role.endswith(" rod"):
            length = float(np.linalg.norm(h.capsule[1] - h.capsule[0]))
            joint = next(j.index for j in asm.joints if j.kind == "rod")
            rows.append({"item": f"{h.role}, cut to {np.ceil(length):.0f} mm",
                         "quantity": 1, "for": f"the grounding column and axle of joint "
                                               f"{joint}"})
    glued = [w for w, k in (("the rod in the grounded link, the base and its cap", "rod"),
                            ("the dowels in their blind bores and their caps", "dowel"))
             if any(j.kind == k for j in asm.joints)]
    if pieces is not None:
        glued.append(f"link {pieces.link}'s pieces on their dowel pins")
    if glued:
        rows.append({"item": "two-part epoxy or cyanoacrylate glue", "quantity": 1,
                     "for": "; ".join(glued)})
    printed = Counter(p.role for p in asm.parts
                      if pieces is None or (p.link, p.role) != (pieces.link, "link"))
    if pieces is not None:
        printed["link piece"] = len(pieces.meshes)
    for role, n in sorted(printed.items()):
        rows.append({"item": f"printed {role}" + ("s" if n > 1 else ""), "quantity": n,
                     "for": f"{material.name}"})
    return rows


def parts_entry(asm: Assembly, meshes: dict[str, trimesh.Trimesh],
                material: profiles.Material, pieces: split.Split | None = None) -> list[dict]:
    """Per printed part: link, role, box extents, volume and mass; a link printed in
    ``pieces`` says so (``printed_as``) and its pieces follow it (role ``"link piece"``)."""
    def row(name: str, link: int, role: str) -> dict:
        return {"name": name, "link": link, "role": role,
                "obb_extents_mm": np.sort(meshes[name].bounding_box_oriented.primitive.extents
                                          ).tolist(),
                "volume_cm3": meshes[name].volume / 1e3,
                "mass_g": meshes[name].volume / 1e3 * material.density_g_cm3}

    rows = []
    for p in asm.parts:
        rows.append(row(p.name, p.link, p.role))
        if pieces is not None and p.link == pieces.link and p.role == "link":
            rows[-1]["printed_as"] = pieces.entry()
            rows += [row(n, pieces.link, "link piece") for n in pieces.meshes]
    return rows


def step_colors(asm: Assembly) -> dict[str, np.ndarray]:
    """RGB of each printed part of ``asm`` in ``assembly.step``, by name."""
    return {p.name: color_of(-1 if p.role == "base" else p.link) for p in asm.parts}


def step_files(asm: Assembly, report: dict, job: StepJob | None = None
               ) -> list[tuple[str, bytes]]:
    """``parts.step`` and ``assembly.step`` (:mod:`step`; by ``job``'s helper process when
    it was handed ``asm``, :mod:`step_job`); each of ``report``'s ``parts`` gains ``step``:
    ``"exact"``, ``"exact, polyhedral fillet"`` or ``"faceted"`` (a link's printed piece:
    none)."""
    out, kinds = (job or StepJob(spawn=False)).result(asm, step_colors(asm), STEEL)
    for entry in report.get("parts", []):  # a link's printed pieces: its solid stands for them
        entry["step"] = kinds.get(entry["name"], "none: in its link's solid")
    return out


def report_json(report: dict) -> bytes:
    """``report.json``'s bytes, strict JSON (a non-finite number is written as null)."""
    def finite(x):
        if isinstance(x, dict):
            return {k: finite(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [finite(v) for v in x]
        if isinstance(x, (np.floating, np.integer, np.bool_)):
            x = x.item()
        return None if isinstance(x, float) and not np.isfinite(x) else x

    return json.dumps(finite(report), indent=2, allow_nan=False).encode()


def files(asm: Assembly, report: dict, material: profiles.Material, *, rhino: bool = False
          ) -> tuple[list[tuple[str, bytes]], dict[str, trimesh.Trimesh], list]:
    """``(files, meshes, placements)``: the module docstring's files (without the guide);
    ``report`` gains ``print_layout``, ``parts`` and ``bill_of_materials``."""
    entries, meshes, placements = report_entries(asm, material)
    out = [(f"{name}.stl", tm.export(file_type="stl")) for name, tm in meshes.items()]
    out += layout.plate_files(meshes, placements)
    out.append(("assembly.glb", assembly_glb(asm, meshes)))
    if rhino:
        from paraloop_core.fabrication import rhino as rhino_mod  # optional dependency

        out.append(("paraloop.3dm", rhino_mod.assembly_3dm(
            meshes, {p.name: color_of(p.link) for p in asm.parts})))
    report.update(entries)
    pieces = next((p for p in entries["parts"] if "printed_as" in p), None)
    if pieces is not None:  # it does not stand on its bosses: its pieces lie flat
        report["warnings"] = [w for w in report.get("warnings", [])
                              if not w.startswith(f"link {pieces['link']} cannot lie on")]
    big = [p["name"] for p in entries["print_layout"]["parts"] if not p["fits_bed"]]
    if big:  # only at a size the maker chose: the automatic size shrinks until all fit
        report.setdefault("warnings", []).append(
            f"{', '.join(big)} do{'es' * (len(big) == 1)} not fit the bed laid on its print "
            "face: choose a smaller size or a larger printer")
    for p in entries["print_layout"]["parts"]:
        if p["support_share"] > layout.SUPPORT_AIM:
            why = " (it carries the end-effector, which no face lays flat)" if \
                p["name"].startswith("link_3") and "end_effector" in report else ""
            report.setdefault("warnings", []).append(
                f"{p['name']} needs support under {100 * p['support_share']:.0f} % of its "
                f"downward-facing area{why}: print it with supports (print_layout)")
    return out, meshes, placements


def report_entries(asm: Assembly, material: profiles.Material
                   ) -> tuple[dict, dict[str, trimesh.Trimesh], list]:
    """``(entries, meshes, placements)``: what the export adds to the report
    (``print_layout``, ``parts``, ``bill_of_materials``, ``scale_mm_per_unit``), the parts'
    meshes (home frame, mm; an end link printed in pieces, :mod:`split`, also as its pieces)
    and the bed placements of what is printed; :func:`files` without the files (the studio's
    summary of the parts on screen)."""
    meshes = part_meshes(asm)
    down = downs(asm)
    placements = layout.bed_layout(meshes, down, asm.printer.bed_mm)
    pieces = split.split_end_link(asm, meshes["link_3"], down["link_3"])
    if pieces is not None:  # the pieces are printed in its place
        printed = {n: m for n, m in meshes.items() if n != "link_3"} | pieces.meshes
        placements = layout.bed_layout(printed, down | pieces.downs, asm.printer.bed_mm)
        meshes = meshes | pieces.meshes
    entries = {"print_layout": layout.layout_entry(placements, asm.printer.bed_mm),
               "parts": parts_entry(asm, meshes, material, pieces),
               "bill_of_materials": bill_of_materials(asm, material, pieces),
               "scale_mm_per_unit": asm.scale}
    return entries, meshes, placements
