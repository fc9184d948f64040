"""The printed size of the realization on screen, for the status sentence: ``(size, bar
width)`` in mm for the Fabrication folder's settings (:func:`app.exports.print_estimate`: the
size *Export all* aims at and the thinnest bar the sizing gives this realization there; the
export may realize the loop again with roomier joints and thicker bars).

Sizing needs the consecutive bars' proven bounds (``Realization.joint_lower``) and a small
linear programme, too slow for a drag's release: it runs on its own thread once the studio
has been quiet for :data:`QUIET` s, and ``on_ready`` redraws the status when it is done.
"""

from __future__ import annotations

import threading
import time
import traceback
from collections.abc import Callable
from typing import Any

from app.exports import print_estimate
from app.state import FabSettings
from app.worker import FULL, NewestWorker
from paraloop_core.errors import FabricationError

#: Seconds without a preview or full update before a size is computed (as the Drive folder).
QUIET = 0.15
#: Sizes remembered (undo/redo shows them at once).
KEEP = 16

Size = tuple[float, float | None] | str  # (size mm, bar width mm or None) or why not


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
            size: Size = print_estimate(real, fab)
        except FabricationError:  # not sizeable at all (the export says why)
            size = "it cannot be sized for print (Export all says why)"
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
