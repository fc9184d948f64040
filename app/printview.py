"""What you see is what you print (issue 28): the printed parts of the loop on screen, built
in the background and drawn in place of the solid links.

After every worker job the studio hands the solution on screen to :meth:`PrintView.update`.
Once the studio has been quiet for :data:`QUIET` s (no drag preview or full update), this
module's thread builds the parts of that solution's realization with the Fabrication
folder's options and the design's drive (:func:`app.printjob.build` in a child process: the
build takes seconds and would hold the interpreter during a drag; the newest request wins,
an edit kills an obsolete build at once). The parts are drawn on the worker's path: the
thread asks for a ``FRAME`` job and :meth:`PrintView.update` draws them inside
``server.atomic()`` with :meth:`SceneView.set_parts`, tied to the realization they were
built for, so any edit shows the solid links again (the fast approximation, also while
dragging) until new parts arrive. A line under the status says while they are being built;
the *Printed object* card and its physics check are :mod:`app.panels.summary`.

The printed loop may be another of the motion's nine loops than the design's, or the
design's realized again with roomier joints (``printed.make``): its parts are posed by its
own joint factors (the same motion, so they move with the targets and the slider) and the
card says which loop is printed. ``PARALOOP_STUDIO_PARTS=0`` switches the builder off (the
solid links only: a slow machine; tests that do not look at the parts).
"""

from __future__ import annotations

import dataclasses
import functools
import multiprocessing
import os
import sys
import threading
import time
from typing import TYPE_CHECKING, Any

from app.exports import options_of
from app.panels.summary import SummaryCard, first_sentence, physics_text
from app.printjob import Parts, serve
from app.worker import FRAME, FULL, PREVIEW, NewestWorker
from paraloop_core.design import Design

if TYPE_CHECKING:
    from app.host import StudioHost

#: Seconds without a preview or full update before the parts are built (as ``app.sizes``).
QUIET = 0.15
#: Environment variable: ``0`` switches the builder off.
ENV = "PARALOOP_STUDIO_PARTS"
#: Seconds between looks at the child's pipe (how soon an obsolete build is killed).
POLL = 0.1

#: The card when the design on screen has no realization to print.
NO_LOOP = ("*No printed parts: the design on screen has no collision-free loop (see the "
           "status).*")

Key = tuple  # (realization (compared by identity), printable.Options, DriveSettings)


def enabled() -> bool:
    """Whether the studio builds the printed parts (:data:`ENV`, default on)."""
    return os.environ.get(ENV, "1").strip() != "0"


def same(a: Key | None, b: Key | None) -> bool:
    """Whether two keys ask for the same parts: the same realization object, equal options
    and drive settings."""
    if a is None or b is None:
        return a is b
    return a[0] is b[0] and a[1:] == b[1:]


@functools.cache
def _context() -> Any:
    """The child processes' start method: a fork server with the core imported (a build
    starts in milliseconds, from a process without the studio's threads), else spawn."""
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["app.printjob"])
        return ctx
    return multiprocessing.get_context("spawn")


@dataclasses.dataclass
class _Child:
    """A build's child process, its pipe, and what it sent."""

    key: Key
    process: Any
    conn: Any
    parts: Parts | None = None
    ended: bool = False  # refused or failed: it serves nothing more


class PrintView:
    """The printed parts of the solution on screen (module docstring)."""

    def __init__(self, studio: StudioHost, order: float, on: bool | None = None) -> None:
        self.studio = studio
        self.on = enabled() if on is None else on
        self.card = SummaryCard(studio.server.gui, order, self.request_physics)
        if not self.on:
            self.card.show(None, f"*Printed parts are switched off ({ENV}=0): solid bars "
                                 "stand in for them; Export all still builds them.*")
        self._lock = threading.Lock()
        self._want: tuple[Key | None, Any] = (None, None)  # (key, solution) on screen
        self._ready: tuple[Key, Parts] | None = None  # built, for the worker to draw
        self._drawn: Key | None = None  # the parts in the scene (worker thread)
        self.parts: Parts | None = None  # and what they are
        self._active = 0.0  # monotonic time of the last preview or full update
        self._physics = False  # a physics check asked for
        self._closed = False
        self._child: _Child | None = None  # the builder thread's
        self.timings: list[float] = []  # seconds from quiet to the parts built
        self._worker = NewestWorker(self._compute, name="studio-parts")

    # --- the studio's worker ----------------------------------------------------------------
    def update(self, sol: Any, design: Design, level: int) -> None:
        """After each worker job of ``level`` with ``sol`` on screen (``design``: the design
        the job drew, for its drive settings): ask for the parts of a new realization, drop
        parts that no longer belong on screen, draw parts that arrived."""
        if not self.on:
            return
        real = None if sol is None else sol.realization
        key = None if real is None else (real, options_of(self.studio.state.fab),
                                          design.drive)
        with self._lock:
            if level >= PREVIEW:
                self._active = time.monotonic()
            changed = not same(key, self._want[0])
            if changed:
                self._want = (key, sol)
            ready = self._ready
        if changed:
            self._worker.request(FULL)
            if self._drawn is not None:
                self.card.stale()
        if self._drawn is not None and not same(self._drawn, key):
            self._draw(None, None)
        if ready is not None and same(ready[0], key) and not same(self._drawn, key):
            self._draw(*ready)

    def _draw(self, key: Key | None, parts: Parts | None) -> None:
        """Put ``parts`` (None: none) in the scene for the realization of ``key``."""
        scene, st = self.studio.scene, self.studio.state
        with self.studio.server.atomic():
            if parts is None:
                scene.set_parts(scene.joint_factors, None)
            else:
                scene.set_parts(parts.joint_factors, list(parts.meshes), list(parts.hardware),
                                shown_for=key[0])
            scene.draw_frame(st.u, st.thickness)
            scene.apply_layers(st.hidden)
        self._drawn, self.parts = key, parts
        if parts is not None:
            self.card.show(parts)

    # --- the physics check ------------------------------------------------------------------
    def request_physics(self) -> None:
        """*Run physics check* (GUI thread): on the parts on screen, in the background."""
        if not self.on or self._drawn is None:
            self.studio.notify("Physics check", "no printed parts to check yet: they are "
                               "built a moment after the design settles", error=True,
                               cause="physics")
            return
        self._physics = True
        self.card.physics.content = ("*Running the physics check (MuJoCo, one cycle of the "
                                     "parts above; several seconds)...*")
        self._worker.request(FULL)

    # --- the builder's thread ---------------------------------------------------------------
    def _compute(self, _level: int) -> None:
        while (wait := self._active + QUIET - time.monotonic()) > 0:
            time.sleep(wait)
        with self._lock:
            key, sol = self._want
        child = self._child
        if child is not None and not same(child.key, key):
            self._stop_child()
            child = None
        if key is None:
            self.card.progress(None)
            self._physics = False
            self.card.show(None, NO_LOOP)
            return
        with self._lock:
            ready = self._ready
        if child is None and not self._physics and ready is not None and same(ready[0], key):
            return  # built before (an undo): the worker draws them
        if child is None:
            child = self._start(key, sol)
            t0 = time.monotonic()
            if not self._wait(child):
                return
            if child.parts is not None:
                self.timings.append(time.monotonic() - t0)
        if self._physics and child.parts is not None and not child.ended:
            self._physics = False
            child.conn.send(("physics", key[2]))
            if not self._wait(child):
                self.card.physics.content = "*Physics check stopped: the design changed.*"

    def _start(self, key: Key, sol: Any) -> _Child:
        """A child process building the parts of ``sol`` for ``key``."""
        ctx = _context()
        mine, theirs = ctx.Pipe()
        sol = dataclasses.replace(sol, design=dataclasses.replace(sol.design, drive=key[2]))
        process = ctx.Process(target=serve, args=(theirs, sol, key[1]), daemon=True,
                              name="paraloop-printed-parts")
        self.card.progress(0.0)
        process.start()
        theirs.close()
        self._child = _Child(key, process, mine)
        return self._child

    def _obsolete(self, child: _Child) -> bool:
        with self._lock:
            return self._closed or not same(self._want[0], child.key)

    def _wait(self, child: _Child) -> bool:
        """Handle the child's messages until its answer (True) or until it is obsolete,
        closed or gone (False; the child is stopped)."""
        while True:
            if self._obsolete(child):
                self._stop_child()
                return False
            try:
                if not child.conn.poll(POLL):
                    continue
                kind, *args = child.conn.recv()
            except (EOFError, OSError):  # killed from outside, or it crashed
                self._stop_child()
                self.card.progress(None)
                self.card.show(None, "*The printed parts could not be built: their builder "
                                     "stopped unexpectedly (see the server log); edit the "
                                     "design to try again.*")
                return False
            if kind == "progress":
                self.card.progress(args[0])  # the core's step names are jargon
                continue
            self._answer(child, kind, args)
            return True

    def _answer(self, child: _Child, kind: str, args: list) -> None:
        """The child's answer: parts, a physics report, a refusal or a bug."""
        building = child.parts is None
        if kind == "done":
            child.parts = args[0]
            with self._lock:
                self._ready = (child.key, child.parts)
            self.studio.request(FRAME)  # the worker draws them
        elif kind == "physics":
            self.card.physics.content = physics_text(args[0])
        elif kind == "refused":
            child.ended = building
            text = first_sentence(args[0])
            if building:
                self.card.show(None, f"**These parts cannot be printed:** {text}. The solid "
                                     "bars show the loop; Export all says more.")
            else:
                self.card.physics.content = f"**The physics check could not run:** {text}."
        else:  # a bug: the log has the traceback, the page a sentence
            child.ended = building
            print(args[0], file=sys.stderr)
            what = "building the printed parts" if building else "the physics check"
            self.studio.notify("Internal error", f"{what} failed (see the server log)",
                               error=True)
            if building:
                self.card.show(None, "*The printed parts could not be built (an internal "
                                     "error, see the server log).*")
            else:
                self.card.physics.content = ""
        if building:
            self.card.progress(None)

    def _stop_child(self) -> None:
        """End the child process (at once: terminate, then kill)."""
        child, self._child = self._child, None
        if child is None:
            return
        child.conn.close()
        if child.process.is_alive():
            child.process.terminate()
            child.process.join(2.0)
            if child.process.is_alive():
                child.process.kill()
        child.process.join(2.0)
        self.card.progress(None)

    # --- tests and closing ------------------------------------------------------------------
    @property
    def drawn(self) -> Key | None:
        """The key of the parts in the scene (None: none)."""
        return self._drawn

    def wait_idle(self, timeout: float = 120.0) -> bool:
        """Block until nothing is pending or being built (tests)."""
        return self._worker.wait_idle(timeout)

    def close(self) -> None:
        with self._lock:
            self._closed = True
        self._worker.close()
        self._stop_child()
