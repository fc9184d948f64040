"""The printed size of the realization on screen, for the status sentence: ``(size, bar
thickness)`` in mm as *Export all* would choose them for the Fabrication folder's settings
(:func:`app.exports.sizing_of`).

Sizing needs the consecutive bars' proven bounds (``Realization.joint_lower``, 15 - 50 ms on
the examples, computed once per realization), too slow for a drag's release: it runs on its
own thread once the studio has been quiet for :data:`QUIET` s, and ``on_ready`` redraws the
status when it is done.
"""

from __future__ import annotations

import threading
import time
import traceback
from collections.abc import Callable
from typing import Any

from app.exports import sizing_of
from app.state import FabSettings
from app.worker import FULL, NewestWorker
from paraloop_core.errors import FabricationError

#: Seconds without a preview or full update before a size is computed (as the Drive folder).
QUIET = 0.15
#: Sizes remembered (undo/redo shows them at once).
KEEP = 16

Size = tuple[float, float] | str  # (size mm, bar thickness mm) or why not printable


class PrintSizes:
    """Printed sizes of realizations, computed on a thread of their own."""

    def __init__(self, on_ready: Callable[[], None]) -> None:
        self._on_ready = on_ready
        self._lock = threading.Lock()
        self._done: list[tuple[Any, FabSettings, Size]] = []  # (realization, settings, size)
        self._want: tuple[Any, FabSettings] | None = None
        self._active = 0.0
        self._worker = NewestWorker(self._compute, name="studio-sizes")

    def busy(self) -> None:
        """A preview or full update ran: sizing waits until the studio is quiet."""
        self._active = time.monotonic()

    def get(self, real: Any, fab: FabSettings) -> Size | None:
        """The size of ``real`` at ``fab``, or None while it is being measured (asked for)."""
        with self._lock:
            for r, f, size in self._done:
                if r is real and f == fab:
                    return size
            self._want = (real, fab)
        self._worker.request(FULL)
        return None

    def _compute(self, _level: int) -> None:
        while (wait := self._active + QUIET - time.monotonic()) > 0:
            time.sleep(wait)
        with self._lock:
            want, self._want = self._want, None
        if want is None:
            return
        real, fab = want
        try:
            sz = sizing_of(real, fab)
            size: Size = (sz.size_mm, 2.0 * sz.bar_radius_mm)
        except FabricationError as exc:  # a size below the printer profile's minimum
            need = str(exc).rpartition("needs at least ")[2]
            size = (f"too small to print at {fab.size_mm:.0f} mm (needs {need}): change "
                    "Size (mm) in Fabrication" if need != str(exc) else
                    "it cannot be sized for print (see Details)")
        except Exception:  # a bug: the status keeps its text, the log says why
            traceback.print_exc()
            return
        with self._lock:
            self._done = [*self._done, (real, fab, size)][-KEEP:]
        self._on_ready()

    def wait_idle(self, timeout: float = 30.0) -> bool:
        """Block until no size is pending or being computed (tests)."""
        return self._worker.wait_idle(timeout)

    def close(self) -> None:
        self._worker.close()
