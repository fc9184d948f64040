"""The printed object in a few lines (issue 28): a line under the status while the printed
parts are being built, and the *Printed object* folder: a card with the figures a maker asks
for (size on the bed, thinnest bar, joint hardware, weight, motor torque, whether it stands,
supports, the collision check) and *Run physics check*.

Every figure is read from the report of the parts on screen (``app.printjob.Parts.report``,
the same entries *Export all* writes to ``report.json``); the texts are functions of it
(:func:`card_text`, :func:`physics_text`). The widgets are written by ``app.printview``.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from typing import Any

import viser

from app.panels.design import handler
from app.printjob import Parts
from app.wording import gui_text
from paraloop_core.fabrication import drive_mass, profiles

#: The card before any parts are built.
WAITING = "*The printed parts are built a moment after the design settles.*"
NOT_RUN = "*Physics check: not run for these parts.*"


def first_sentence(text: str, limit: int = 240) -> str:
    """The core's message (CLI options in the studio's words) up to its first ``': '`` (what
    follows lists every candidate tried), at most ``limit`` characters."""
    head = gui_text(text).split(": ")[0].strip().rstrip(".")
    return head if len(head) <= limit else head[:limit - 3].rstrip() + "..."


def hardware_text(report: dict) -> str:
    """The joints' hardware in words, e.g. ``'5 M3 x 45 mm screws with lock nuts and washers,
    a 6 mm steel rod as the column'`` (a report's ``joints`` and ``base``)."""
    screws: Counter = Counter()
    pins = dowels = 0
    for j in report["joints"]:
        if j["kind"] in profiles.FASTENERS:
            screws[(profiles.FASTENERS[j["kind"]].name, j["screw_length_mm"])] += 1
        elif j["kind"] == "dowel":
            dowels += 1
        elif j["kind"] != "rod":
            pins += 1
    parts = []
    if screws:
        sizes = [f"{n} {name} x {length:g} mm" for (name, length), n in sorted(screws.items())]
        parts.append(" and ".join(sizes) + " screws with lock nuts and washers")
    if pins:
        parts.append(f"{pins} printed pin{'s' * (pins > 1)} with caps")
    if dowels:
        parts.append(f"{dowels} steel dowel{'s' * (dowels > 1)} with printed caps")
    base = report.get("base")
    if base is not None and any(j["kind"] == "rod" for j in report["joints"]):
        parts.append(f"a {base['rod']} as axle and column")
    return ", ".join(parts) or "none"


def _stands(report: dict) -> str:
    base = report.get("base")
    if base is not None and base["stands"]:
        return (f"yes, on a {base['plate_diameter_mm']:.0f} mm plate; its centre of mass stays "
                f"{100 * base['com_margin_share']:.0f} % of the plate's width inside the rim")
    return f"no: {gui_text(str(report.get('mount') or 'screw the plate down'))}"


def card_text(parts: Parts) -> str:
    """The card for ``parts`` (module docstring): every figure from ``parts.report``."""
    r = parts.report
    sz, links, layout = r["sizing"], r["stiffness"]["links"], r["print_layout"]
    if parts.same_loop:
        head = (f"**Printed as the design's loop {parts.loop}**, realized again with roomier "
                "joints for real screws")
    else:
        head = (f"**Printed as loop {parts.loop}** (the design's is loop {parts.design_loop}), "
                "realized again with roomier joints: its parts are shown")
    thin = min(links, key=lambda e: e["width_mm"])
    slender = max(links, key=lambda e: e["length_per_width"])
    bed = layout["bed_mm"]
    fits = all(p["fits_bed"] for p in layout["parts"])
    plates = layout["plates"]
    support = max(layout["parts"], key=lambda p: p["support_share"])
    printed = [p for p in r["parts"] if "printed_as" not in p]  # a link's pieces, not it
    plastic = sum(p["mass_g"] for p in printed)
    drive = r["drive"]
    lines = [
        head,
        f"- **Size:** {sz['size_mm']:.0f} mm across; {len(printed)} parts on {plates} "
        f"plate{'s' * (plates > 1)} of the {bed[0]:.0f} x {bed[1]:.0f} mm bed"
        + ("" if fits else " - **a part does not fit the bed**"),
        f"- **Thinnest bar:** {thin['width_mm']:.1f} mm wide (link {thin['link']}); the most "
        f"slender is {slender['length_per_width']:.0f} times as long as wide "
        f"(link {slender['link']})",
        f"- **Joints:** {hardware_text(r)}",
    ]
    if "error" in drive:
        lines.append(f"- **Weight:** {plastic:.0f} g of printed parts")
        lines.append(f"- **Motor:** torque not computed ({first_sentence(drive['error'])})")
    else:
        total = 1e3 * sum(drive["link_masses_kg"])
        lines.append(f"- **Weight:** {total:.0f} g in all, {plastic:.0f} g of it printed "
                     f"{drive['material']}")
        if drive_mass.by_hand(drive):
            lines.append("- **Motor:** none; turn it by hand, holding the base and a link "
                         "across the loop: " + drive_mass.hand_reason(drive))
        else:
            lines.append(f"- **Motor:** {drive['peak_torque_n_m']:.2g} N·m at most on joint "
                         f"{drive['motor']} (turned slowly)")
    lines += [
        f"- **Stands:** {_stands(r)}",
        "- **Supports:** " + (
            "none needed" if support["support_share"] <= 0 else
            f"at most {100 * support['support_share']:.0f} % of a part's downward faces "
            f"({support['name']})"),
    ]
    v = r["verification"]
    lines.append(
        f"- **Collision check:** {'passed' if v['ok'] else '**failed**'}, least gap between "
        f"links without a common joint {v['min_non_adjacent_gap_mm']:.1f} mm at "
        f"{parts.samples} points of the cycle and, by a proven motion bound, between them")
    lines += [f"- *Note:* {gui_text(w)}" for w in r["warnings"]]
    return "\n".join(lines)


def physics_text(rep: dict) -> str:
    """The physics check's result (:func:`printed.physics_check`'s report) in words."""
    ok = "✓" if rep["ok"] else "✗"
    cycle = ("completes the cycle" if rep["completed"] else
             f"**does not follow the loop** (pose error {rep['max_pose_error_mm']:.2g} mm)")
    n = rep["non_adjacent_contacts"]
    contact = ("no contact between links without a common joint" if n == 0 else
               f"**{n} contacts** between links without a common joint")
    if rep.get("drive") == "hand":
        base = (f"turned by hand (the base held, link {rep['hand_link']} moved: no motor "
                "drives this loop, see Motor above)")
    elif rep.get("anchored"):
        base = "held by its resting link (no base)"
    elif rep["stands"]:
        base = f"the base does not tip (tilt {rep['base_tilt_deg_max']:.1f}°)"
    else:
        base = f"**the base tips** ({rep['base_tilt_deg_max']:.0f}°)"
    quasi = rep.get("peak_torque_quasi_static_nm")
    torque = "" if rep.get("drive") == "hand" else (
        f", motor torque {rep['peak_torque_dynamic_nm']:.2g} N·m with inertia"
        + ("" if quasi is None else f" ({quasi:.2g} turned slowly)"))
    return (f"**Physics check {ok}** (MuJoCo, one {rep['sim_seconds']:.0f} s cycle, "
            f"{rep['wall_seconds']:.0f} s to run): {cycle}, {contact}, {base}{torque}.")


class SummaryCard:
    """The building line (placed at ``order``, under the status) and the *Printed object*
    folder; ``on_physics()`` is called when *Run physics check* is pressed (GUI thread)."""

    def __init__(self, gui: viser.GuiApi, order: float, on_physics: Callable[[], Any]) -> None:
        self.building = gui.add_markdown("*Building printed parts ...*", order=order,
                                         visible=False)
        with gui.add_folder("Printed object", order=order + 0.001):
            self.text = gui.add_markdown(WAITING)
            self.physics_button = gui.add_button(
                "Run physics check", disabled=True, icon=viser.Icon.PLAYER_PLAY,
                hint="simulate the parts above through one cycle (MuJoCo: their masses, the "
                     "motor, gravity, standing on a table; turned by hand instead where no "
                     "motor drives the loop): does it complete the cycle, do parts "
                     "touch, does the base tip, and the torque with inertia; takes several "
                     "seconds, in the background")
            self.physics = gui.add_markdown(NOT_RUN)
        self.physics_button.on_click(handler(lambda _: on_physics()))

    def progress(self, fraction: float | None) -> None:
        """The building line: ``fraction`` done, or hidden (None)."""
        if fraction is None:
            self.building.visible = False
            return
        self.building.content = (f"*Building printed parts ... ({100 * fraction:.0f} %): "
                                 "solid bars stand in for them until they are ready.*")
        self.building.visible = True

    def show(self, parts: Parts | None, text: str | None = None) -> None:
        """The card of ``parts`` (physics not run), or ``text`` without parts."""
        self.text.content = card_text(parts) if parts is not None else (text or WAITING)
        self.physics.content = NOT_RUN if parts is not None else ""
        self.physics_button.disabled = parts is None

    def stale(self) -> None:
        """The design changed: the card describes the parts before the change."""
        self.physics_button.disabled = True
        if not self.text.content.startswith(("*(For the design before", "*No printed parts",
                                             WAITING)):
            self.text.content = ("*(For the design before your last change: new parts follow "
                                 "when it settles.)*\n\n" + self.text.content)
