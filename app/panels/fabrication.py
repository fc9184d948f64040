"""The studio's Fabrication folder: settings, *Carve design spaces* and *Export all (zip)*.

Handlers validate a setting into ``state.fab`` or queue a task (``state.add_task``); the
studio runs the task (:meth:`FabricationPanel.run`) as a background job (``app.jobs``: the
worker keeps drawing edits, *Cancel job* stops it) with a progress bar, draws the carved
spaces inside ``server.atomic()`` and shows the continuous-motion bound and the verification
result. Failures become notifications; the design is never changed.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING, Any

import numpy as np
import viser

from app.exports import CUSTOM, ORDER_PRESETS, carve_spaces, export_zip, parse_order, size_of
from app.jobs import Cancelled
from app.panels.design import handler, writing_back
from app.scene import SPACES_LAYER
from app.state import FabSettings
from app.wording import gui_text
from app.worker import FRAME
from paraloop_core.errors import FabricationError
from paraloop_core.fabrication import drive_mass, profiles

if TYPE_CHECKING:
    from app.host import StudioHost

BOUND_HELP = ("Voxel carving is approximate; the bound makes it safe: every sweep is sampled "
              "so that no point of the moving space is farther than the motion margin from a "
              "sampled position (a proven Bernstein bound on the speed of the rational "
              "motion), and each removal reaches that margin plus the voxel balls. The carved "
              "spaces are therefore disjoint for the **continuous** motion.")


#: The *Column on link* entries: the best link (None) or link 0..5.
COLUMN_LINKS = ("best", *(f"link {i}" for i in range(6)))


def check_setting(key: str, value: Any) -> Any:
    """The validated value of setting ``key`` (a widget's value); raises ValueError with a
    readable reason."""
    if key == "ground_link":
        return None if value == COLUMN_LINKS[0] else COLUMN_LINKS.index(value) - 1
    if key in ("size_mm", "clearance_mm", "space_radius_mm"):
        value = float(value)
        if not math.isfinite(value):
            raise ValueError("must be a finite number")
        if value < 0:
            raise ValueError(f"must be >= 0 mm, got {value:g}")
    elif key == "resolution":
        value = int(value)
        if not (value == 0 or 16 <= value <= 256):
            raise ValueError(f"voxels per space must be 0 (automatic) or 16..256, got {value}")
    elif key == "custom_order" and value.strip():
        parse_order(value)
    elif key == "bed" and value.strip():
        profiles.parse_bed(value)
    elif key == "printer" and value not in profiles.PRINTERS:
        raise ValueError(f"unknown printer {value!r}")
    return value


STALE = "*(stale: the design changed since; run it again)* "


class FabricationPanel:
    """GUI of the Fabrication folder; ``studio`` supplies state, worker, scene and files."""

    def __init__(self, server: viser.ViserServer, studio: StudioHost) -> None:
        self.studio = studio
        self.server = server
        gui, fab = server.gui, studio.state.fab
        self.report: dict | None = None  # the last export's report.json
        self.report_for: Any = None  # the realization that export was made from
        self._version = -1  # design version the running task started from
        self.carving: dict | None = None  # the last carving's report
        self.progress_log: list[tuple[str, float]] = []
        self._made_for: Any = None  # the realization the texts below describe
        self._stale = False
        with gui.add_folder("Fabrication", expand_by_default=False):
            self.inputs: dict[str, Any] = {
                "size_mm": gui.add_number(
                    "Size (mm)", initial_value=fab.size_mm, step=10.0,
                    hint="longest side of the linkage in mm; 0 = automatic: the largest size "
                         "at which every part fits the printer's bed"),
                "printer": gui.add_dropdown(
                    "Printer", tuple(profiles.PRINTERS), initial_value=fab.printer,
                    hint="printer profile: build volume, walls, fits (generic: 250 x 210 x "
                         "210 mm, any well-calibrated 0.4 mm nozzle printer)"),
                "bed": gui.add_text(
                    "Bed X,Y,Z (mm)", fab.bed,
                    hint="your printer's build volume, e.g. 375,315,315; empty = the "
                         "profile's. A design whose joints find no room names the bed that "
                         "would print it"),
                "clearance_mm": gui.add_number(
                    "Joint clearance (mm)", initial_value=fab.clearance_mm, step=0.05,
                    hint="gap between a pin and its bore, in mm (your printer's tolerance)"),
                "print_in_place": gui.add_checkbox(
                    "Print in place", fab.print_in_place,
                    hint="print the loop assembled (captive pins) instead of as parts"),
                "ground": gui.add_checkbox(
                    "Grounding column", fab.ground,
                    hint="a column under one link so the loop stands on a table "
                         "(Sec. 5.3, loop grounding)"),
                "ground_link": gui.add_dropdown(
                    "Column on link", COLUMN_LINKS, initial_value=COLUMN_LINKS[0],
                    hint="the link that carries the grounding column and rests on the table; "
                         "best = the one whose column clears the moving links best"),
                "space_radius_mm": gui.add_number(
                    "Space radius (mm)", initial_value=fab.space_radius_mm, step=1.0,
                    hint="design-space radius; 0 = the realization's (median), base link x2"),
                "resolution": gui.add_number(
                    "Voxels per space", initial_value=fab.resolution, min=0, max=256, step=8,
                    hint="voxels along each design space; 0 = automatic (128..256, so that "
                         "every space is several voxels thick); carving is approximate, the "
                         "continuous-motion bound below keeps it safe"),
                "order": gui.add_dropdown(
                    "Carving order", (*ORDER_PRESETS, CUSTOM), initial_value=fab.order,
                    hint="which link's space is carved by which first (Sec. 5.2): earlier "
                         "links keep more room"),
                "custom_order": gui.add_text("Custom pairs", fab.custom_order,
                                             hint="target-source, all 15 pairs: 0-1, 0-2, ..."),
                "carved_parts": gui.add_checkbox(
                    "Parts from carved spaces", fab.carved_parts,
                    hint="export each link as its carved design space instead of a bar"),
            }
            self.carve = gui.add_button(
                "Carve design spaces", icon=viser.Icon.CUBE,
                hint="the room each link may fill without ever touching the others (voxels, "
                     "approximate; the bound below keeps it safe); runs in the background")
            self.export = gui.add_button(
                "Export all (zip)", icon=viser.Icon.DOWNLOAD,
                hint="printable parts (STL, 3MF), assembly guide and a verification report; "
                     "runs in the background")
            self.progress = gui.add_progress_bar(0.0, visible=False)
            self.progress_text = gui.add_markdown("")
            self.bound = gui.add_markdown("*Design spaces: not carved yet.*")
            self.verification = gui.add_markdown("*Verification: not exported yet.*")
        for key, handle in self.inputs.items():
            handle.on_update(handler(lambda _, key=key: self._set(key)))
        self.carve.on_click(handler(lambda e: self._task("carve", e)))
        self.export.on_click(handler(lambda e: self._task("export", e)))

    # --- handlers (edit the state only) -----------------------------------------------------
    def _set(self, key: str) -> None:
        st = self.studio.state
        try:
            value = check_setting(key, self.inputs[key].value)
        except ValueError as exc:
            old = getattr(st.fab, key)
            self.studio.notify("Fabrication setting", f"{exc}; kept {old!r}", error=True)
            self.studio.request(FRAME, sync=True)  # writes the kept value back
            return
        st.fab = dataclasses.replace(st.fab, **{key: value})
        self.studio.request(FRAME)  # the status's size and the printed parts follow it

    def _task(self, name: str, event: Any) -> None:
        self.studio.state.add_task(name, event.client)
        self.studio.request(FRAME)

    # --- worker side ------------------------------------------------------------------------
    def sync(self, fab: FabSettings) -> None:
        """Show ``fab`` in the widgets (no handler fires)."""
        with writing_back():
            for key, handle in self.inputs.items():
                value = getattr(fab, key)
                handle.value = COLUMN_LINKS[0 if value is None else value + 1] \
                    if key == "ground_link" else value

    def mark_stale(self, sol: Any) -> None:
        """Mark the carving and export texts stale when ``sol``'s realization is not the one
        they were made for (the design changed since)."""
        stale = self._made_for is not None and sol.realization is not self._made_for
        if stale and not self._stale:
            for text in (self.bound, self.verification):
                text.content = STALE + text.content
        self._stale = self._stale or stale

    def _fresh(self, sol: Any) -> None:
        """The results are about to describe ``sol``: drop the stale marks."""
        self._made_for, self._stale = sol.realization, False
        for text in (self.bound, self.verification):
            text.content = text.content.removeprefix(STALE)

    def run(self, task: str, client: Any) -> None:
        """Run a queued task on the last valid solution (worker thread)."""
        studio = self.studio
        title = "Carving" if task == "carve" else "Export"
        if studio.solution is None:
            studio.notify(f"{title} failed", studio.error or "no solution yet", error=True)
            return
        self.progress_log.clear()
        self._version = studio.state.version
        self._progress(0.0, "starting", title)
        try:
            sol = studio.solution
            self._fresh(sol)
            if task == "carve":
                self._carve(sol)
            else:
                self._export(sol, client)
        except Cancelled as exc:
            why = str(exc) if exc.by_user else "the design changed; press the button again"
            studio.notify(f"{title} cancelled", why, cause="job")
            self.progress_text.content = f"{title} cancelled ({why})."
        except (FabricationError, ValueError) as exc:
            studio.notify(f"{title} failed", f"{exc} (the design is unchanged)", error=True)
            self.progress_text.content = gui_text(f"{title} failed: {exc}")
        finally:
            self.progress.visible = False

    def _progress(self, fraction: float, message: str, title: str) -> None:
        """Show progress; *Cancel job* or a design edit since the task started cancels it."""
        self.studio.jobs.check()
        if self.studio.state.version != self._version:
            raise Cancelled(by_user=False)
        self.progress_log.append((message, fraction))
        self.progress.visible = True
        self.progress.value = 100.0 * min(max(fraction, 0.0), 1.0)
        self.progress_text.content = f"{title}: {message} ({100 * fraction:.0f} %)"

    def _carve(self, sol: Any) -> None:
        real, fab = sol.realization, self.studio.state.fab
        if real is None:
            raise FabricationError("the design has no realization (switch Realize on)",
                                   "bad-parameters")
        cv, bodies = carve_spaces(sol, fab, lambda f, m: self._progress(f, m, "Carving"))
        studio, st = self.studio, self.studio.state
        with self.server.atomic():
            studio.scene.set_spaces(real.joint_factors, bodies)
            studio.show_layer(SPACES_LAYER)  # carved to be seen (Construction folder)
            studio.scene.draw_frame(st.u, st.thickness)
            studio.scene.apply_layers(st.hidden)
        self.carving = cv.report
        margin = cv.report["max_motion_margin"]
        size = size_of(sol, fab)
        mm = margin * size / float(np.max(np.ptp(real.points, axis=0)))
        empty = [i for i, b in enumerate(bodies) if b is None]
        self.bound.content = (
            f"**Continuous-motion bound:** motion margin {margin:.3g} design units "
            f"= {mm:.3g} mm at {size:.0f} mm. {BOUND_HELP} "
            f"Carved at {cv.report['resolution']} voxels per space in "
            f"{cv.report['seconds']:.1f} s, voxels kept {cv.report['voxels']}"
            + (f"; too thin to mesh: links {empty}." if empty else "."))
        self.progress_text.content = f"Carving done ({len(bodies) - len(empty)} spaces)."
        if len(empty) == len(bodies):
            self.studio.notify("No design space to show", "every carved space is too thin to "
                               "mesh; raise the voxels per space or the space radius",
                               error=True)

    def _export(self, sol: Any, client: Any) -> None:
        studio = self.studio
        if studio.error:
            studio.notify("Exporting the last valid design", studio.error, error=True)
        name, data, report = export_zip(sol, studio.state.fab,
                                        lambda f, m: self._progress(f, m, "Export"))
        studio.send_file(client, name, data)
        self.report_for = sol.realization  # first: a reader of a new report finds its source
        self.report = report
        if report is None:
            studio.notify("Exported the result only", "the design has no realization, so "
                          "there are no parts", error=True)
            self.verification.content = "*Verification: no realization, no parts.*"
            self.progress_text.content = f"Exported {name}."
            return
        v, sz, b = report["verification"], report["sizing"], report.get("base")
        word = "ok ✓" if v["ok"] else "FAILED ✗"
        stands = "no base" if b is None else ("stands on its base" if b["stands"] else
                                              "screw its base down")
        self.verification.content = (
            f"**Size {sz['size_mm']:.0f} mm**, bars {min(sz['bar_width_mm']):.1f} - "
            f"{max(sz['bar_width_mm']):.1f} mm wide, {stands}. "
            f"**Verification: {word}** least gap between links without a common joint "
            f"{v['min_non_adjacent_gap_mm']:.1f} mm over the whole cycle, joint clearance "
            f"{v['joint_clearance_mm']:.2f} mm. {report['choice']['note']}. "
            f"**Drive:** {drive_mass.drive_line(report['drive'])}")
        self.progress_text.content = f"Exported {name}."
        if not v["ok"]:
            studio.notify("Verification failed", "see report.json in the zip", error=True)
        elif report["warnings"]:
            studio.notify("Exported, with notes", " ".join(report["warnings"]))
