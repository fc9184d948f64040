"""One background thread that always computes the newest request.

Requests carry a level (``FRAME`` < ``PREVIEW`` < ``FULL`` < ``REFINE``, the multi-start fit
that follows a fit design's quick full update); requests made while the worker is
busy merge into one pending job at the highest level asked for, so rapid gizmo events collapse
and never queue up. A watchdog calls ``on_slow`` when a job runs longer than ``slow_after``
seconds and the worker calls ``on_slow_done`` when that job ends (the progress indicator).
"""

from __future__ import annotations

import threading
import time
import traceback
from collections.abc import Callable

FRAME, PREVIEW, FULL, REFINE = 0, 1, 2, 3


class NewestWorker:
    """Run ``job(level)`` on one thread for the newest merged request."""

    def __init__(
        self,
        job: Callable[[int], None],
        *,
        on_slow: Callable[[], None] | None = None,
        on_slow_done: Callable[[], None] | None = None,
        slow_after: float = 0.3,
        name: str = "studio-worker",
    ) -> None:
        self._job = job
        self._on_slow = on_slow
        self._on_slow_done = on_slow_done
        self._slow_after = slow_after
        self._cond = threading.Condition()
        self._pending: int | None = None
        self._running = False
        self._stop = False
        self._job_started = 0.0
        self._slow_fired = False
        self.jobs_run = 0
        self._thread = threading.Thread(target=self._loop, name=name, daemon=True)
        self._watchdog = threading.Thread(target=self._watch, name=name + "-watch", daemon=True)
        self._thread.start()
        self._watchdog.start()

    def request(self, level: int) -> None:
        """Ask for a job at ``level`` (merged with any pending request)."""
        with self._cond:
            self._pending = level if self._pending is None else max(self._pending, level)
            self._cond.notify_all()

    def wait_idle(self, timeout: float = 10.0) -> bool:
        """Block until nothing is pending or running (tests, benchmarks)."""
        end = time.monotonic() + timeout
        with self._cond:
            while self._pending is not None or self._running:
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self._cond.wait(left)
            return True

    def close(self) -> None:
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        self._thread.join(timeout=5.0)
        self._watchdog.join(timeout=5.0)

    def _loop(self) -> None:
        while True:
            with self._cond:
                while self._pending is None and not self._stop:
                    self._cond.wait()
                if self._stop:
                    return
                level, self._pending = self._pending, None
                self._running = True
                self._job_started = time.monotonic()
                self._cond.notify_all()
            try:
                self._job(level)
            except Exception:  # keep the worker alive; the job reports its own errors
                traceback.print_exc()
            with self._cond:
                if self._slow_fired:
                    self._slow_fired = False
                    self._call_unlocked(self._on_slow_done)
                self._running = False
                self.jobs_run += 1
                self._cond.notify_all()

    def _watch(self) -> None:
        with self._cond:
            while not self._stop:
                if not self._running:
                    self._cond.wait()
                    continue
                started = self._job_started
                left = started + self._slow_after - time.monotonic()
                if left > 0:
                    self._cond.wait(left)
                    continue
                self._slow_fired = True
                if self._on_slow is not None:  # under the lock: runs before on_slow_done
                    try:
                        self._on_slow()
                    except Exception:
                        traceback.print_exc()
                while self._running and self._job_started == started and not self._stop:
                    self._cond.wait()

    def _call_unlocked(self, fn: Callable[[], None] | None) -> None:
        if fn is None:
            return
        self._cond.release()
        try:
            fn()
        except Exception:
            traceback.print_exc()
        finally:
            self._cond.acquire()
