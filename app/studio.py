"""``paraloop studio``: the browser design studio (viser server).

Handlers edit :class:`~app.state.StudioState` and ask the :class:`~app.worker.NewestWorker` for
an update; the worker solves the newest design with :func:`pipeline.solve` and draws it inside
``server.atomic()``: a cheap preview while a gizmo is dragged (motion, factorizations, axes)
and a full update with the realization on release. Failures become notifications (one per
cause, ``app.notices``) while the last valid solution stays on screen; fits, carvings and
exports are long jobs with *Cancel job* (``app.jobs``). On open and after *Load design* the
camera frames everything (``app.camera``), afterwards the user's camera is kept.
"""

from __future__ import annotations

import argparse
import dataclasses
import signal
import sys
import threading
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np
import viser

from app import camera
from app.files import EXAMPLES, FileTransfers, studio_design
from app.jobs import Cancelled, Jobs
from app.notices import Notices
from app.panels.design import Panels, writing_back
from app.panels.drive import DrivePanel
from app.panels.fabrication import FabricationPanel
from app.plots import Plots
from app.printview import PrintView
from app.restore import RestoreOffer, offer_restore
from app.scene import HIDDEN_AT_START, SceneView
from app.solver import Solver, incomplete
from app.state import StudioState, autosave_path_for, migrate_autosave, uploaded_meshes_dir
from app.status import StatusLine, details, error_headline, scale_warning
from app.worker import FRAME, FULL, PREVIEW, REFINE, NewestWorker
from paraloop_core import design as design_mod
from paraloop_core import pipeline
from paraloop_core.design import Design
from paraloop_core.errors import DesignFileError, ParaloopError
from paraloop_core.motion.evolution import evolution_settings

#: Shortest time between two autosaves (s): an edit is written at once, further edits of a
#: drag at most this long after it (so on disk within 2 s, whatever the worker is doing).
AUTOSAVE_SECONDS = 0.5


class Studio(FileTransfers):
    """The studio bound to one viser server (several browser tabs share it); file transfers
    in :class:`app.files.FileTransfers`."""

    def __init__(self, server: viser.ViserServer, design: Design,
                 autosave_path: Path | None = None) -> None:
        self.server = server
        self.state = StudioState(design, autosave_path)
        self.state.hidden = set(HIDDEN_AT_START)  # the construction aids start hidden
        self.solution: pipeline.Solution | None = None  # last valid solution (on screen)
        self.error: str | None = None  # why the current design has no solution
        self.downloads: list[tuple[str, bytes]] = []
        self.notices = Notices(server)
        self.notifications = self.notices.log  # (title, body, error), newest last
        self.jobs = Jobs(self._busy, self._bug)
        self.restore_offer: RestoreOffer | None = None
        # frame the camera: "open" after the next full update, "keep" (Frame all: each page
        # keeps its direction) at the next job
        self._frame_pending: str | None = "open"
        # the browsers' cameras the opening framing set (client id -> position), framed again
        # on the printed parts when they arrive unless moved since (None: nothing to do)
        self._aimed: dict[int, np.ndarray] | None = None
        self.solver = Solver()  # cached, warm-started solves
        self.timings: dict[int, list[float]] = {PREVIEW: [], FULL: [], REFINE: [], FRAME: []}
        self._need_sync = True
        self._drawn = (-1, -1)  # (version, level) of the design on screen
        self._refine_for = -1  # the version whose quick update awaits its REFINE job
        self._busy_frame: tuple[float, tuple] = (0.0, ())  # (when, what) a long job drew
        self.scene = SceneView(server, self._on_gizmo)
        self.panels = Panels(server, self)
        self.status = StatusLine(self.panels.show_status, lambda: self.state.fab)
        self.panels.frame.on_click(lambda _: self._frame_request())
        self.panels.cancel.on_click(lambda _: self.jobs.cancel())
        self.fabrication = FabricationPanel(server, self)
        self.drive = DrivePanel(server, self, self.fabrication)
        self.plots = Plots(server)
        self.printview = PrintView(self, self.panels_order() + 0.02)  # the printed parts
        busy = self.panels.busy  # a job longer than 0.3 s: a line under the status, no toast
        self.worker = NewestWorker(self._job, on_slow=lambda: setattr(busy, "visible", True),
                                   on_slow_done=lambda: setattr(busy, "visible", False))
        self._stop = threading.Event()
        self._player = threading.Thread(target=self._play, name="studio-player", daemon=True)
        self._player.start()
        self._saver = threading.Thread(  # the autosave: neither worker nor search delays it
            target=self.state.keep_saved, name="studio-autosave", daemon=True,
            args=(self._stop, self._autosave_failed, AUTOSAVE_SECONDS))
        self._saver.start()
        self.request(FULL, sync=True)

    # --- requests from handlers -------------------------------------------------------------
    def request(self, level: int, sync: bool = False) -> None:
        """Ask the worker for an update; ``sync`` also rewrites gizmos and widgets."""
        if sync:
            self._need_sync = True
        self.worker.request(level)

    def _on_gizmo(self, i: int, event: viser.TransformControlsEvent) -> None:
        if event.phase == "start":
            return
        end = event.phase == "end"
        g = event.target
        if self.state.move_pose(i, g.position, g.wxyz, commit=end):
            self.request(FULL if end else PREVIEW)
        elif end:  # a locked target: snap the gizmo back
            self.request(FULL, sync=True)

    # --- feedback ---------------------------------------------------------------------------
    def notify(self, title: str, body: str, error: bool = False, cause: str | None = None
               ) -> None:
        """Show a notification in every open page, replacing the one of the same ``cause``
        (default: the title); errors stay longer."""
        self.notices.notify(title, body, error, cause)

    def panels_order(self) -> float:
        """GUI order of the status line (offers are placed just below it)."""
        return float(self.panels.status.order)

    def reframe(self) -> None:
        """Frame the camera after the next full update (a design opened or replaced)."""
        self._frame_pending = "open"

    def show_layer(self, name: str) -> None:
        """Switch a scene layer on and tick its checkbox (worker thread)."""
        with writing_back():
            self.panels.view.show(name, self.state.hidden)

    def _frame_request(self) -> None:
        """*Frame all*: frame every page at the worker's next job, keeping its direction."""
        if self._frame_pending is None:
            self._frame_pending = "keep"
        self.request(FRAME)

    def frame_all(self, keep_direction: bool = False) -> None:
        """*Frame all* (``keep_direction``): every page keeps its direction and shows the
        targets, the trajectory and the object; else (a design opened) the object and the
        free targets, from the direction showing the object largest (``camera``). Places
        the target labels for that view (worker thread)."""
        if keep_direction:
            self._aimed = None
            view = camera.frame_all(self.server, self.scene.all_shot()) or self.scene.view
        else:
            view, self._aimed = camera.frame_object(self.server, self.scene.object_shot())
        with self.server.atomic():
            self.scene.set_view(view)

    def _frame_parts(self) -> None:
        """The printed parts arrived after an opening framing: frame them (the object) in
        every page whose camera stayed where that framing put it, and for new pages."""
        aimed, self._aimed = self._aimed or {}, None
        start = np.asarray(self.server.initial_camera.position, float)  # pages opened since
        clients = [c for cid, c in self.server.get_clients().items()
                   if camera.unmoved(c.camera, aimed.get(cid, start))]
        view, _ = camera.frame_object(self.server, self.scene.object_shot(), clients)
        with self.server.atomic():
            self.scene.set_view(view)

    def _busy(self, job: str | None) -> None:
        """Show *Cancel job* while a long job runs."""
        self.panels.cancel.visible = job is not None
        if job is not None:
            self.panels.cancel.label = f"Cancel job ({job})"
        else:  # an export's parts may give the Drive folder its torque
            self.worker.request(FRAME)

    # --- the worker's job -------------------------------------------------------------------
    def _job(self, level: int) -> None:
        try:
            self._update(level)
            for task, arg in self.state.take_tasks():  # after the update
                if task == "mesh":
                    self.panels.effector.check_mesh(arg)
                elif task in ("result", "animation"):
                    self.send_download(task, arg)
                elif not self.jobs.start(task, lambda task=task, arg=arg:
                                         self.fabrication.run(task, arg)):
                    self.notify(f"Cannot start the {task}", f"the {self.jobs.busy} is still "
                                "running: wait for it or press Cancel job", error=True,
                                cause="job")
        except Exception as exc:  # a bug, not bad input: keep serving and say so
            self._bug(exc)

    def _bug(self, exc: Exception) -> None:
        """A bug in the worker's job or a background job: logged and shown in the page."""
        traceback.print_exc()
        self.notify("Internal error", f"{exc!r} (see the server log)", error=True)

    def _update(self, level: int) -> None:
        start = time.perf_counter()
        design, version = self.state.snapshot()
        sync, self._need_sync = self._need_sync, False
        if sync:
            with self.server.atomic():
                self.scene.set_targets(design)
                self.panels.sync(design)
                self.fabrication.sync(self.state.fab)
                self.drive.sync(design)
        if level == REFINE and version != self._refine_for:  # edited since: a plain update
            level = FULL
        stale = version != self._drawn[0] or level > self._drawn[1]
        if level >= PREVIEW and stale:
            self.status.sizes.busy()
            self._solve_and_draw(design, version, level)
        else:
            with self.server.atomic():
                self.scene.draw_frame(self.state.u, self.state.thickness)
                self.scene.apply_layers(self.state.hidden)
            self.status.refresh()  # the Fabrication settings may have changed the size
        key = level if level >= PREVIEW and stale else FRAME
        self.timings[key].append(time.perf_counter() - start)
        self.drive.update(self.solution, design.drive, level)  # planned on its own thread
        self.printview.update(self.solution, design, level)  # built in a child process
        if self._aimed is not None and self.scene.parts_shown():
            self._frame_parts()
        frame, self._frame_pending = self._frame_pending, None
        if frame == "keep" or (frame == "open" and level == FULL):
            self.frame_all(keep_direction=frame == "keep")  # targets alone if nothing solved
        else:
            self._frame_pending = frame

    def _autosave_failed(self, exc: OSError) -> None:
        self.notify("Autosave failed", f"{exc}; use Save design", error=True, cause="autosave")

    def _solve(self, design: Design, level: int) -> tuple[pipeline.Solution, str]:
        """:meth:`Solver.solve`. A fit design's full update takes the fit of its last drag
        preview (:meth:`Solver.quick_fit`) and asks for ``REFINE``: the multi-start fit, run
        as a long job (progress, *Cancel job*), shown only if it fits better. A full update
        whose quick realization search finds nothing asks for ``REFINE`` too: the full
        search, as a job (*Cancel job*; superseded by any edit)."""
        if level < FULL:
            return self.solver.solve(design, False, self.solution)
        version, fit = self.state.version, design.motion.method == "fit"
        if level == FULL:
            quick = (self.solver.quick_fit(design) if fit else
                     self.solver.solve(design, True, self.solution, quick=True))
            if quick is not None:
                if fit or incomplete(quick[0]):
                    self._refine_for = version
                return quick
        shown = self.solution

        def check() -> None:
            self.jobs.check()
            if self.state.version != version:  # a newer edit supersedes this job
                raise Cancelled(by_user=False)
            self._frame_while_busy()

        def progress(fraction: float, message: str) -> None:
            check()
            self.status.set(f"Fitting the motion to the poses ({100 * fraction:.0f} %)...",
                            f"Fitting: {message}")

        with self.jobs.running("fit" if fit else "realization search"):
            sol, note = self.solver.solve(design, True, self.solution,
                                          progress if fit else None, check=check)
        if fit and level == REFINE and shown is not None and shown.fit is not None \
                and shown.fit.cost <= sol.fit.cost:  # the drag's fit stays: it fits better
            sol, note = dataclasses.replace(shown, design=design), ""
            if incomplete(sol):  # its quick search missed: the full search, on that fit
                with self.jobs.running("realization search"):
                    sol, note = self.solver.complete(design, sol.fit, check)
            self.solver.remember(design, sol, note)
        return sol, note

    def _frame_while_busy(self) -> None:
        """During a long job on the worker (fit, full search): *Frame all* at once, and redraw
        the frame, at most 30 times a second, when the slider, Play or the layers moved it."""
        if self._frame_pending == "keep":
            self._frame_pending = None
            self.frame_all(keep_direction=True)
        now = time.monotonic()
        if now - self._busy_frame[0] < 1.0 / 30.0:
            return
        seen = (self.state.u, self.state.thickness, tuple(sorted(self.state.hidden)))
        if seen != self._busy_frame[1]:
            with self.server.atomic():
                self.scene.draw_frame(self.state.u, self.state.thickness)
                self.scene.apply_layers(self.state.hidden)
        self._busy_frame = (now, seen)

    def _solve_and_draw(self, design: Design, version: int, level: int) -> None:
        full = level >= FULL
        t0 = time.perf_counter()
        self._refine_for = -1
        try:
            sol, note = self._solve(design, level)
        except Cancelled as exc:
            if exc.by_user:  # keep the last valid solution
                self._drawn = (version, level)
                what = "Fit" if design.motion.method == "fit" else "Search"
                self.status.set(f"{what} cancelled - the last result is shown; edit the "
                                "design to start again", f"{what} cancelled with Cancel job.")
                self.notify(f"{what} cancelled", "stopped as you asked", cause="job")
            return  # else a newer edit is pending and supersedes it
        except ValueError as exc:  # ParaloopError and other bad input
            self.error = str(exc)
            self._drawn = (version, level)
            shown = "the last valid design is shown" if self.solution else "nothing to show"
            text = error_headline(exc, self.state.last_moved, self.solution is not None)
            self.status.set(text, f"Cannot solve the design: {exc} ({shown}).")
            if full and self.state.version == version:  # superseded errors are dropped
                self.notify("Cannot solve the design", f"{text} (more in Details)",
                            error=True, cause="solve")
            return
        self.notices.clear("solve")
        ms = 1e3 * (time.perf_counter() - t0)
        self.solution, self.error, self._drawn = sol, None, (version, level)
        if full and sol.realization is not None:
            self.solver.realized = sol
        hint = self.solver.realized
        preview = None if full or hint is None else self.solver.preview
        with self.server.atomic():
            self.scene.draw_motion(sol)
            self.scene.draw_factorizations(sol)
            self.scene.set_loop(sol, preview, None if preview is None else
                                hint.realization.radius)
            self.scene.draw_frame(self.state.u, self.state.thickness)
            self.scene.apply_layers(self.state.hidden)
            if full:
                self.panels.show_solution(sol)
                self.plots.update(sol)
        if full:
            self.fabrication.mark_stale(sol)
        refine = None
        if self._refine_for == version:
            refine = (evolution_settings(design.evolution).starts
                      if design.motion.method == "fit" else 0)
            self.worker.request(REFINE)
        sol = dataclasses.replace(sol, design=design)
        searching = refine is not None and incomplete(sol)
        text = self.status.solution(
            details(sol, full=full, ms=ms, note=note, ghost=self.scene.ghost is not None,
                    moved=preview is not None, refine_starts=refine or None,
                    searching=searching),
            sol=sol, full=full, moved=preview is not None, searching=searching,
            refining=bool(refine), last_moved=self.state.last_moved)
        if note and full and self.state.version == version:
            self.notify("No collision-free loop", f"{text} (more in Details)", error=True,
                        cause="solve")
        self.panels.rescale.visible = bool(scale_warning(design))

    def _play(self) -> None:
        """Animation frames at 30 Hz."""
        last = time.monotonic()
        while not self._stop.wait(1.0 / 30.0):
            now = time.monotonic()
            dt, last = now - last, now
            if self.state.playing:
                self.state.u = (self.state.u + self.state.speed * dt) % 1.0
                self.panels.set_u(round(self.state.u, 3))
                self.worker.request(FRAME)

    def close(self) -> None:
        self.jobs.cancel()
        self._stop.set()
        self._player.join(timeout=2.0)
        self._saver.join(timeout=2.0)
        self.worker.close()
        self.status.close()
        self.drive.close()
        self.printview.close()
        self.jobs.wait(10.0)
        try:
            self.state.autosave()
        except OSError as exc:
            self._autosave_failed(exc)


def default_design_path() -> Path:
    """The first example design in ``assets/designs``."""
    found = sorted(EXAMPLES.glob("*.json"))
    if not found:
        raise DesignFileError("file", f"no example designs in {EXAMPLES}")
    return found[0]


def run_studio(design_path: str | Path | None, host: str = "127.0.0.1", port: int = 8080) -> int:
    """Serve the studio until SIGINT/SIGTERM; prints the URL."""
    opened = Path(design_path) if design_path is not None else None
    path = opened or default_design_path()
    design = studio_design(design_mod.load_design(path, (str(uploaded_meshes_dir()),)))
    server = viser.ViserServer(host=host, port=port, verbose=False)
    autosave = autosave_path_for(opened, design.name)
    try:
        migrate_autosave(autosave)  # from the data folder of earlier versions
    except OSError as exc:
        print(f"could not move the old autosave to {autosave}: {exc}")
    studio = Studio(server, design, autosave)
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    message = offer_restore(studio, path if opened else None)
    if message:
        print(message)
    print(f"paraloop studio: {design.name} ({path}); autosave: {autosave}")
    print(f"open http://{host}:{server.get_port()}/", flush=True)
    try:
        while not stop.wait(0.5):
            pass
    finally:
        studio.close()
        server.stop()
    return 0


def register(subparsers: Any) -> None:
    """Add the ``studio`` sub-command to the ``paraloop`` CLI."""
    p = subparsers.add_parser("studio", help="open the design studio in the browser")
    p.add_argument("design", nargs="?", help="design JSON (default: an example design)")
    p.add_argument("--host", default="127.0.0.1", help="interface to serve on")
    p.add_argument("--port", type=int, default=8080, help="port (0 picks a free one)")
    p.set_defaults(func=lambda args: run_studio(args.design, args.host, args.port))


def main(argv: list[str] | None = None) -> int:
    """``python -m app.studio [DESIGN] [--host H] [--port N]``."""
    parser = argparse.ArgumentParser(prog="paraloop studio")
    sub = parser.add_subparsers(dest="command")
    register(sub)
    args = parser.parse_args(["studio", *(sys.argv[1:] if argv is None else argv)])
    try:
        return int(args.func(args))
    except ParaloopError as exc:  # a bad design file: one line, like the paraloop CLI
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
