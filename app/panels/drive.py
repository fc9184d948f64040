"""The studio's Drive folder (issue 16): the motor, cycle time and speed limits of the design's
``drive`` settings, every joint's speed over the cycle (motor at constant speed and with the
recommended speed schedule, :func:`drive_plan.plan_drive`) and the motor torque from the
fabricated parts' masses.

Handlers only validate a value into ``Design.drive`` (one undoable edit) and ask for a full
update. The plan (20-25 ms, up to 0.4 s for infeasible limits) is computed on this panel's own
thread after the studio's worker has drawn a full update and gone quiet
(:meth:`DrivePanel.update`), so drag previews and releases never wait for it.
"""

from __future__ import annotations

import dataclasses
import threading
import time
import traceback
from typing import TYPE_CHECKING, Any

import numpy as np
import viser
import viser.uplot as uplot

from app.panels.design import handler, writing_back
from app.worker import FRAME, FULL, PREVIEW, NewestWorker
from paraloop_core import design_checks
from paraloop_core.design import Design, DriveSettings
from paraloop_core.fabrication.drive_mass import material
from paraloop_core.linkage.drive import TWO_PI
from paraloop_core.linkage.drive_plan import DrivePlan, plan_drive

if TYPE_CHECKING:
    from app.host import StudioHost

RECOMMENDED = "Recommended"
MOTORS = (RECOMMENDED, *(f"joint {j}" for j in range(6)))
JOINT_COLORS = ("#d62728", "#2ca02c", "#1f77b4", "#bcbd22", "#9467bd", "#17becf")
NO_PARTS = ("*Motor torque: run Fabrication (Export all) to compute the torque from the "
            "parts' masses.*")
#: Seconds without a preview or full update before a plan is computed: a plan takes 20-25 ms
#: of the shared interpreter, so it waits until the user lets go rather than slow a drag.
QUIET = 0.15


def parse_limit(text: str) -> float | None:
    """A limit field: blank (or ``auto``) -> None (chosen by the program), else the number.
    Raises ValueError for other text."""
    text = text.strip()
    if text.lower() in ("", "auto"):
        return None
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"'{text}' is not a number (leave it blank for automatic)") from None


def checked(design: Design, key: str, value: Any) -> Design:
    """``design`` with ``drive.<key> = value``, validated as the design file is (raises
    :class:`DesignFileError`, a ValueError, naming the field and its range)."""
    drive = dataclasses.replace(design.drive, **{key: value})
    fields = design_checks.drive(dataclasses.asdict(drive))  # the file's rules, drive only
    return dataclasses.replace(design, drive=DriveSettings(**fields))


def _speed_chart(gui: Any, title: str) -> Any:
    series = (uplot.Series(label="time (s)"),
              *(uplot.Series(label=f"joint {j}", stroke=c, width=2)
                for j, c in enumerate(JOINT_COLORS)),
              uplot.Series(label="speed limit", stroke="#7f7f7f", width=1.5, dash=(6.0, 4.0)))
    return gui.add_uplot(
        tuple(np.zeros(2) for _ in series), series, title=title, aspect=1.4,
        scales={"x": uplot.Scale(time=False)},
        axes=(uplot.Axis(label="time in the cycle (s)"), uplot.Axis(label="speed (rad/s)")))


def speed_data(time_s: np.ndarray, velocity: np.ndarray, limit: float) -> tuple:
    """Chart data: time ``(N,)`` s, the six joints' speeds ``|velocity|`` ``(N, 6)`` rad/s
    (each joint turns one way), the speed limit (rad/s) as a constant series."""
    speed = np.abs(velocity)
    return (time_s, *speed.T, np.full(len(time_s), limit))




def _same_realization(a: Any, b: Any) -> bool:
    """The same bars: equal joint factors and points (a re-solve may return a new object)."""
    return (a is not None and b is not None and np.array_equal(a.joint_factors, b.joint_factors)
            and np.array_equal(a.points, b.points))


def _same_key(a: tuple, b: tuple) -> bool:
    """``(solution, settings, report)`` keys: the same objects, equal settings."""
    return bool(b) and a[0] is b[0] and a[1] == b[1] and a[2] is b[2]


class DrivePanel:
    """The Drive folder; ``fabrication`` (its last export's ``report``) gives the parts'
    torque. :meth:`update` and :meth:`sync` are called from the studio's worker."""

    def __init__(self, server: viser.ViserServer, studio: StudioHost, fabrication: Any) -> None:
        self.studio, self.server, self.fabrication = studio, server, fabrication
        gui = server.gui
        self.plan: DrivePlan | None = None  # the plan on screen
        self.ms: list[float] = []  # time of each plan computed (ms)
        self._lock = threading.Lock()
        self._source: tuple[Any, DriveSettings] | None = None  # last full solution, settings
        self._report: tuple[Any, Any] = (None, None)  # (export report, realization it is for)
        self._key: tuple = ()  # (solution, settings, report) of the newest request
        self._active = 0.0  # monotonic time of the studio's last preview or full update
        self._planned: tuple = ()  # (joint factors, settings, resting link) of self.plan
        with gui.add_folder("Drive", expand_by_default=False):
            self.inputs: dict[str, Any] = {
                "motor": gui.add_dropdown(
                    "Motor joint", MOTORS, initial_value=RECOMMENDED,
                    hint="the joint the motor turns; Recommended: the joint whose drive is "
                         "smoothest (the smallest fastest-joint speed ratio below), preferring "
                         "the two joints of the grounded link"),
                "cycle_time_s": gui.add_number(
                    "Cycle time (s)", initial_value=10.0, min=0.01, max=1e6, step=0.5,
                    hint="seconds for one full cycle of the loop"),
                "max_speed_ratio": gui.add_text(
                    "Max speed ratio", "",
                    hint="limit for every joint: its fastest speed divided by its average "
                         "speed over the cycle (a number >= 1, no unit); blank = chosen by "
                         "the program (shown below)"),
                "max_accel_rad_s2": gui.add_text(
                    "Max acceleration (rad/s²)", "",
                    hint="limit for every joint's angular acceleration, in rad/s²; blank = "
                         "chosen by the program (shown below)"),
                "density_kg_m3": gui.add_number(
                    "Material density (kg/m³)", initial_value=1240.0, min=1.0, max=1e5,
                    step=10.0, hint="density of the printed parts in kg/m³ (1240 = PLA): "
                                    "their masses give the motor torque (Export all)"),
            }
            self.summary = gui.add_markdown("*Drive: waiting for the design to solve.*")
            self.constant = _speed_chart(gui, "Joint speeds, motor at constant speed")
            self.scheduled = _speed_chart(gui, "Joint speeds with the recommended speed "
                                               "schedule")
            self.torque_text = gui.add_markdown(NO_PARTS)
            self.torque = gui.add_uplot(
                (np.zeros(2), np.zeros(2)),
                (uplot.Series(label="motor angle (deg)"),
                 uplot.Series(label="torque (N·m)", stroke="#ff7f0e", width=2)),
                title="Motor torque over the cycle (fabricated parts)", aspect=1.4,
                scales={"x": uplot.Scale(time=False)},
                axes=(uplot.Axis(label="motor angle (deg)"), uplot.Axis(label="torque (N·m)")),
                visible=False)
        for key, h in self.inputs.items():
            h.on_update(handler(lambda _, key=key: self._set(key)))
        self._worker = NewestWorker(self._compute, name="studio-drive")

    # --- handlers (edit the state only) -----------------------------------------------------
    def _set(self, key: str) -> None:
        h, st = self.inputs[key], self.studio.state
        try:
            if key == "motor":
                value: Any = None if h.value == RECOMMENDED else int(h.value.split()[1])
            elif key in ("max_speed_ratio", "max_accel_rad_s2"):
                value = parse_limit(h.value)
            else:
                value = float(h.value)
            checked(st.design, key, value)
        except ValueError as exc:
            self.studio.notify("Drive setting", f"{exc}; kept the previous value", error=True)
            self.studio.request(FRAME, sync=True)  # writes the kept value back
            return
        st.edit(lambda d: dataclasses.replace(
            d, drive=dataclasses.replace(d.drive, **{key: value})), merge=f"drive.{key}")
        self.studio.request(FULL)

    # --- worker side ------------------------------------------------------------------------
    def sync(self, design: Design) -> None:
        """Show ``design.drive`` in the widgets (no handler fires)."""
        d = design.drive
        with writing_back():
            self.inputs["motor"].value = RECOMMENDED if d.motor is None else f"joint {d.motor}"
            self.inputs["cycle_time_s"].value = d.cycle_time_s
            for key in ("max_speed_ratio", "max_accel_rad_s2"):
                value = getattr(d, key)
                self.inputs[key].value = "" if value is None else f"{value:g}"
            self.inputs["density_kg_m3"].value = d.density_kg_m3

    def update(self, sol: Any, settings: DriveSettings, level: int) -> None:
        """After each worker job of ``level``: a full update's solution and the design's drive
        settings are planned on this panel's thread once the studio is quiet (no preview or
        full job for :data:`QUIET` s); any job notices a finished export (torque)."""
        with self._lock:
            if level >= PREVIEW:
                self._active = time.monotonic()
            if level >= FULL and sol is not None:
                self._source = (sol, settings)
            report = self.fabrication.report
            if report is not self._report[0]:  # an export finished: the realization it
                self._report = (report, self.fabrication.report_for)  # was made from
            if self._source is None:
                return
            key = (*self._source, report)
            if _same_key(key, self._key):
                return
            self._key = key
        self._worker.request(FULL)

    def _inputs(self) -> tuple[Any, DriveSettings, dict | None, tuple]:
        """Snapshot: solution, settings, the parts' drive entry when it is for this
        realization (else None), and the key it was taken for."""
        with self._lock:
            (sol, settings), (report, real), key = self._source, self._report, self._key
        entry = None if report is None else report.get("drive")
        fresh = entry is not None and _same_realization(real, sol.realization)
        other = None if report is None else report.get("choice", {}).get("note")
        if fresh and other:  # the export printed another realization than the studio's
            entry = {**entry, "exported_realization": other}
        return sol, settings, entry if fresh else None, key

    def _quiet(self) -> None:
        """Wait until no preview or full update ran for :data:`QUIET` s (a drag goes on)."""
        while (wait := self._active + QUIET - time.monotonic()) > 0:
            time.sleep(wait)

    def _compute(self, _level: int) -> None:
        self._quiet()
        sol, settings, entry, key = self._inputs()
        jf = sol.loop.joint_factors
        rest = 0 if entry is None or "error" in entry else int(entry["resting_link"])
        try:
            p = self._planned
            if not (p and p[0] is jf and p[1:] == (settings, rest)):
                t0 = time.perf_counter()
                plan = plan_drive(jf, settings, rest)
                self.ms.append(1e3 * (time.perf_counter() - t0))
                self.plan, self._planned = plan, (jf, settings, rest)
        except ValueError as exc:  # a loop the planner refuses (e.g. a degenerate axis)
            self.plan, self._planned = None, ()
            with self.server.atomic():
                self.summary.content = f"**Drive:** ⚠ cannot plan this loop: {exc}"
                self.constant.visible = self.scheduled.visible = False
            return
        except Exception as exc:  # a bug: keep the studio running and say so
            traceback.print_exc()
            self.studio.notify("Internal error", f"drive plan: {exc!r} (see the server log)",
                               error=True)
            return
        with self._lock:
            if not _same_key(key, self._key):  # newer inputs are pending: their run draws
                return
        with self.server.atomic():
            self._draw(self.plan, entry)

    def _draw(self, plan: DrivePlan, entry: dict | None) -> None:
        ct, m = plan.cycle_time_s, plan.motor
        limit = plan.max_speed_ratio * TWO_PI / ct  # rad/s
        self.summary.content = summary_text(plan)
        cs = plan.constant
        t = np.append(cs.theta, TWO_PI) * (ct / TWO_PI)  # closed: the cycle's end = its start
        self.constant.visible = True
        self.constant.title = f"Joint speeds, motor joint {m} at constant speed"
        self.constant.data = speed_data(t, np.vstack([cs.velocity, cs.velocity[:1]]), limit)
        s = plan.schedule
        self.scheduled.visible = s is not None
        if s is not None:
            self.scheduled.title = f"Joint speeds with the recommended schedule of joint {m}"
            self.scheduled.data = speed_data(s.time, s.velocity, limit)
        self.torque.visible = entry is not None and "error" not in entry
        if entry is None:
            self.torque_text.content = NO_PARTS
            return
        self.torque_text.content = torque_text(entry, plan)
        if "error" in entry:
            return
        theta = np.degrees(np.append(entry["theta_rad"], TWO_PI))
        torque = np.asarray(entry["torque_n_m"], float)
        self.torque.data = (theta, np.append(torque, torque[0]))

    def wait_idle(self, timeout: float = 30.0) -> bool:
        """Block until no plan is pending or being computed (tests, benchmarks)."""
        return self._worker.wait_idle(timeout)

    def close(self) -> None:
        self._worker.close()


def _by(who: str) -> str:
    return "chosen by the program" if who == "program" else "yours"


def summary_text(plan: DrivePlan) -> str:
    """The plan for people: motor and why, constant-speed peaks, limits, the schedule or
    why there is none (the planner's message says what would work)."""
    cs, s = plan.constant, plan.schedule
    fast = int(np.argmax(cs.peak_speed_ratio))
    acc = ("none works" if plan.max_accel_rad_s2 is None
           else f"{plan.max_accel_rad_s2:.3g} rad/s²")
    lines = [
        f"**Motor: joint {plan.motor}** ({_by(plan.motor_chosen_by)}): {plan.motor_reason}.",
        f"**At constant motor speed** ({plan.cycle_time_s:g} s per cycle): joint {fast} peaks "
        f"at {cs.peak_speed_ratio[fast]:.3g}x its average speed; largest acceleration "
        f"{cs.peak_accel.max():.3g} rad/s².",
        f"**Limits:** speed ratio {plan.max_speed_ratio:.3g} "
        f"({_by(plan.speed_ratio_chosen_by)}), acceleration {acc} "
        f"({_by(plan.accel_chosen_by)}).",
    ]
    if s is None:
        lines.append(f"**Speed schedule:** ⚠ none meets these limits: {plan.error.rstrip('.')}.")
    else:
        lines.append(
            f"**Speed schedule:** every joint within the limits (peak speed ratio "
            f"{s.achieved_speed_ratio.max():.3g}, acceleration {s.achieved_accel.max():.3g} "
            f"rad/s²); the fastest such cycle takes {s.fastest_cycle_time:.3g} s.")
    return "\n\n".join(lines)


def torque_text(entry: dict, plan: DrivePlan) -> str:
    """The parts' torque (a report's ``drive`` entry) for people, with what differs from the
    panel's settings (the export's motor or density)."""
    if "error" in entry:
        return f"**Motor torque:** ⚠ not computed for the exported parts: {entry['error']}"
    text = (f"**Motor torque** from the fabricated parts: {entry['moving_mass_kg']:.3g} kg "
            f"moving, {material(entry['density_kg_m3'])}; peak "
            f"{entry['peak_torque_n_m']:.3g} N·m for motor joint {entry['motor']} "
            f"(grounded link {entry['resting_link']}).")
    if "exported_realization" in entry:
        text += f" *The export printed another realization: {entry['exported_realization']}*"
    if entry["motor"] != plan.motor or entry["density_kg_m3"] != plan.density_kg_m3:
        text += (f" *Exported for motor joint {entry['motor']} at "
                 f"{entry['density_kg_m3']:g} kg/m³; Export all again for the settings "
                 "above.*")
    return text
