"""The assembly guide beside the parts: ``assembly.md`` and ``assembly.html`` with pictures.

Content (a maker's order): what this is and which loop was printed (and why, when it is not
the design's realization), the bill of materials, the parts with their plate and print face,
print settings for the printer and material, then the assembly: each joint in turn (which
screw, which side the head goes, the nut in its trap, how tight), the rod and the base, the
check by hand, and the motor. Pictures (:mod:`guide_pictures`): the whole loop labelled, one
exploded view per joint, the base.
"""

from __future__ import annotations

import numpy as np

from paraloop_core.fabrication import drive_mass, guide_html, guide_pictures, profiles


def _joint_text(j, first: int) -> str:
    a, b, kind = j.index, (j.index + 1) % 6, j.kind
    if kind in profiles.FASTENERS:
        f = profiles.FASTENERS[kind]
        return (f"Joint {a} joins link {a} and link {b}: put a washer on the {f.name} x "
                f"{j.screw_mm:g} mm screw and push it through link {a} (head side), slide the "
                f"thrust washer on between the two bosses, push the screw through link {b}, "
                "put the third washer on and turn the lock nut on until its nylon ring grips, "
                "then only until the bosses touch the washers without play (a hex key in the "
                f"head, a {f.nut_af_mm:g} mm spanner on the nut); the joint must still turn "
                "freely. The nylon ring holds the nut where you left it.")
    if kind == "printed-pin":
        return (f"Joint {a} joins link {a} and link {b}: push the printed pin_{a} through "
                f"link {a} (head side) and link {b}, then press the printed pin cap onto its "
                "end (a drop of glue if it is loose). The joint must turn freely.")
    if kind == "dowel" and j.blind:
        fixed = j.fixed_link
        free = b if fixed == a else a
        return (f"Joint {a} joins link {a} and link {b} on a {j.axle_d:g} mm steel dowel: "
                "both bars run on along this joint's axis, so nothing sits outside the bosses. "
                f"Glue the dowel into the blind bore of link {fixed} (to its floor), then slide "
                f"link {free}'s blind bore onto it (no glue): its floor keeps link {free} on. "
                "Fit this joint before the loop is closed.")
    if kind == "dowel":
        fixed = j.fixed_link
        free = b if fixed == a else a
        why = (f"no stock screw is as long as this joint (cut a {j.axle_d:g} mm steel rod to "
               f"{j.axle.s1 - j.axle.s0:.0f} mm)" if j.beyond_stock else
               f"link {fixed}'s bar runs on past this joint, so no screw fits")
        return (f"Joint {a} joins link {a} and link {b} on a {j.axle_d:g} mm steel dowel: "
                f"{why}. Glue the dowel "
                f"into the blind bore of link {fixed} (to its floor), slide link {free} on, "
                "then glue the printed dowel cap onto the dowel's end, leaving the joint free "
                f"to turn (no glue on link {free}).")
    if j.blind:
        return (f"Joint {a} joins link {a} and link {b} on the rod (the grounding column): "
                f"push the rod through link {first}'s boss (the grounded link) into the other "
                "link's blind bore until it stops, draw it back half a millimetre and glue it "
                f"in link {first} only; the bore's floor keeps the other link on.")
    return (f"Joint {a} joins link {a} and link {b} on the rod (the grounding column): glue "
            f"the rod into link {first}'s boss (the grounded link), slide the other link on, "
            "then glue the rod cap onto the rod's end, leaving the joint free to turn.")


def assembly_order(joints: tuple) -> list:
    """The joints in the order they are fitted: a chain, the rod's last. The last closes the
    loop, and a dowel in two blind bores cannot be fitted then (the links would have to
    slide along its axis): without a rod the chain ends on another joint."""
    chain = [j for j in joints if j.kind != "rod"]
    if not any(j.kind == "rod" for j in joints):
        open_ = [k for k, j in enumerate(chain) if not (j.kind == "dowel" and j.blind)]
        last = open_[-1] if open_ else len(chain) - 1
        chain = chain[last + 1:] + chain[:last + 1]
    return chain + [j for j in joints if j.kind == "rod"]


def guide_text(asm, report: dict, material: profiles.Material, pictures: dict[str, str]
               ) -> dict:
    """The guide's content as sections of plain text (markdown-safe), shared by the markdown
    and the HTML pages; ``pictures`` maps a picture's role to its file name."""
    sz, choice = report["sizing"], report["choice"]
    widths = np.asarray(sz["bar_width_mm"])
    b = report.get("base")
    printed = [p for p in report["parts"] if "printed_as" not in p]  # pieces, not their link
    mass = sum(p["mass_g"] for p in printed)
    note = choice.get("note", "").removeprefix("printed: ")  # the heading says it
    summary = [
        f"Size: {sz['size_mm']:.0f} mm (longest side of the loop), bars "
        f"{widths.min():.1f} - {widths.max():.1f} mm wide, {mass:.0f} g of "
        f"{material.name} in {len(printed)} printed parts.",
        f"Printed loop: {note}." if note else "",
    ]
    if b is not None:
        summary.append(
            f"Base: a {b['plate_diameter_mm']:.0f} mm plate and a {b['rod']} of "
            f"{b['rod_length_mm']:.0f} mm; " + ("it stands on its own over the whole cycle "
                                                f"(centre of mass at least "
                                                f"{100 * b['com_margin_share']:.0f} % of the "
                                                "plate's diameter inside its rim)."
                                                if b["stands"] else f"{b['mount']}."))
    d = report.get("drive", {})
    if drive_mass.by_hand(d):
        summary.append("Drive: by hand, holding the base and a link across the loop, not by "
                       f"a motor: {drive_mass.hand_reason(d)}.")
    elif "peak_torque_n_m" in d:
        summary.append(f"Motor (optional): on joint {d['motor']}, at least "
                       f"{d['peak_torque_n_m']:.2f} N m against gravity.")
    steps = [(text, pictures.get(f"glue_{p['link']}_{k + 1}"))
             for p in report["parts"] if "printed_as" in p
             for k, text in enumerate(_pieces_text(p))]
    grounded = None if b is None else b["grounded_link"]
    order = assembly_order(asm.joints)
    for k, j in enumerate(order):
        text = _joint_text(j, grounded or 0)
        if k == len(order) - 1 and j.kind != "rod":
            text += " This closes the loop: turn the links until the holes line up."
        steps.append((text, pictures.get(f"joint_{j.index}")))
    if b is not None:
        steps.append(("Glue the rod's lower end into the base plate's socket, flush with the "
                      "plate's underside: the rod stands vertical, the loop above the plate.",
                      pictures.get("base")))
    steps.append(("Turn the loop by hand through its whole cycle: it turns inside out. If a "
                  "joint binds, loosen its nut a quarter turn.", pictures.get("loop")))
    return {"summary": [s for s in summary if s], "steps": steps}


def _pieces_text(part: dict) -> list[str]:
    """The gluing steps of a link printed in pieces (:mod:`split`), one per dowel pin."""
    name = part["name"].replace("_", " ")
    return [f"Glue {name} together ({k + 1} of {len(part['printed_as']['dowels'])}): glue a "
            f"{dw['pin'].replace(', glued', '')} halfway into the bore at the end of "
            f"{dw['pieces'][0]}, then push it into the bore of {dw['pieces'][1]}, glue on the "
            "cut faces, the faces flat on each other and the hexagon's sides in line; let it "
            "set before the joints are assembled."
            for k, dw in enumerate(part["printed_as"]["dowels"])]


def print_settings(printer: profiles.Printer, material: profiles.Material
                   ) -> list[tuple[str, str]]:
    """The print settings the parts are designed for: ``(setting, value)`` rows."""
    return [("printer", f"{printer.name} ({printer.note}); bed "
                        f"{' x '.join(f'{v:g}' for v in printer.bed_mm)} mm"),
            ("material", f"{material.name}, nozzle {material.nozzle_c} C, bed "
                         f"{material.bed_c} C ({material.note})"),
            ("layers", f"{printer.layer_mm:g} mm high; 4 perimeters; 40 % infill (the bars are "
                       "then nearly solid: the stiffness in the report assumes that)"),
            ("orientation", "each part lies on the face the 3MF gives it (bars flat: layers "
                            "along the bar); supports only where the report lists support "
                            "area (touching the bed only)"),
            ("holes", f"drawn {printer.hole_allowance_mm:g} mm over size for this printer; "
                      f"joint clearance {printer.clearance_mm:g} mm")]


def grams(mass_g: float) -> str:
    """A part's mass in words: whole grams, tenths below 10 g (a cap of 0.4 g is not 0)."""
    return f"{mass_g:.0f}" if mass_g >= 9.95 else f"{mass_g:.1f}"


#: Longest step title (characters) taken from a step's first clause (:func:`step_title`).
TITLE_CHARS = 70


def step_title(step: str) -> str:
    """A step's heading: its text up to the first colon or full stop (``Joint 0 joins link
    0 and link 1``), cut at a word within :data:`TITLE_CHARS`."""
    head = step.replace(". ", ": ").split(": ", 1)[0].rstrip(".")
    if len(head) <= TITLE_CHARS:
        return head
    return head[:TITLE_CHARS].rsplit(" ", 1)[0] + " ..."


def markdown(title: str, text: dict, bom: list[dict], parts: list[dict],
             settings: list[tuple[str, str]]) -> bytes:
    """``assembly.md``."""
    lines = [f"# {title}", "", *[f"- {s}" for s in text["summary"]], "",
             "## What you need", "", "| item | quantity | for |", "|---|---|---|",
             *[f"| {r['item']} | {r['quantity']} | {r['for']} |" for r in bom], "",
             "## Parts", "", "| part | size (mm) | mass (g) |", "|---|---|---|",
             *[f"| {p['name']}.stl{' (assembled: print its pieces)' * ('printed_as' in p)} | "
               f"{' x '.join(f'{v:.0f}' for v in sorted(p['obb_extents_mm'], reverse=True))} | "
               f"{grams(p['mass_g'])} |" for p in parts], "",
             "## Print settings", "", *[f"- {k}: {v}" for k, v in settings], "",
             "## Assembly", ""]
    for k, (step, pic) in enumerate(text["steps"]):
        lines += [f"{k + 1}. {step}", ""]
        if pic:
            lines += [f"   ![step {k + 1}]({pic})", ""]
    return "\n".join(lines).encode()


def pages(printed, meshes: dict, placements: list, opts, report: dict
          ) -> list[tuple[str, bytes]]:
    """``assembly.md``, ``assembly.html`` and their pictures (:mod:`guide_pictures`) of a
    printed loop (:mod:`printable`)."""
    asm = printed.assembly
    shots = guide_pictures.assembly_pictures(asm, report["parts"], meshes)
    names = {n: n for n, _ in shots}
    pictures = {"loop": names.get("guide_loop.png"), "base": names.get("guide_base.png")}
    pictures.update({f"joint_{j.index}": names.get(f"guide_joint_{j.index}.png")
                     for j in asm.joints})
    pictures.update({n.removeprefix("guide_").removesuffix(".png"): n for n in names
                     if n.startswith("guide_glue_")})
    text = guide_text(asm, report, opts.material, pictures)
    title = "Assembly guide: a paradoxical 6R loop that turns inside out"
    settings = print_settings(opts.printer, opts.material)
    md = markdown(title, text, report["bill_of_materials"], report["parts"], settings)
    layout = {p["name"]: p for p in report["print_layout"]["parts"]}
    page = guide_html.Guide(
        title=title, summary="\n\n".join(text["summary"]),
        warnings=tuple(report["warnings"]),
        overview=(guide_html.Picture("guide_loop.png", "the assembled loop, links named, "
                                     "joints numbered"),),
        bom=tuple(guide_html.BomLine(r["item"], str(r["quantity"]), r["for"])
                  for r in report["bill_of_materials"]),
        profiles=(guide_html.PrintProfile(f"{opts.printer.name}, {opts.material.name}", tuple(
            guide_html.Fact(k, v) for k, v in settings)),),
        parts=tuple(guide_html.PartRow(
            f"{p['name']}.stl", str(layout[p["name"]]["plate"]),
            "as laid in the 3MF", layout[p["name"]]["support_mm2"],
            f"{grams(p['mass_g'])} g") for p in report["parts"] if p["name"] in layout),
        steps=tuple(guide_html.Step(
            step_title(step), step, () if not pic else (guide_html.Picture(pic, step[:80]),))
            for step, pic in text["steps"]))
    return [*shots, ("assembly.md", md), ("assembly.html", guide_html.guide_html(page))]
