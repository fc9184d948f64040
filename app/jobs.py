"""Long jobs (fit, carving, export) with a *Cancel job* button.

Carving and export run on their own thread, so the worker keeps drawing edits; a fit runs on
the worker inside :meth:`Jobs.running`. Jobs report progress through callbacks that call
:meth:`Jobs.check`, which raises :class:`Cancelled` once *Cancel job* was pressed.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator


class Cancelled(Exception):
    """Raised from a progress callback: ``by_user`` (*Cancel job*), else the design changed
    under the job (a newer edit supersedes it)."""

    def __init__(self, by_user: bool) -> None:
        super().__init__("stopped as you asked" if by_user else "the design changed")
        self.by_user = by_user


class Jobs:
    """At most one long job at a time; ``on_busy(name or None)`` shows or hides the button,
    ``on_error(exception)`` reports a bug in a background job (called in its ``except``)."""

    def __init__(self, on_busy: Callable[[str | None], None],
                 on_error: Callable[[Exception], None]) -> None:
        self._on_busy = on_busy
        self._on_error = on_error
        self._cancel = threading.Event()
        self._lock = threading.Lock()
        self._names: list[str] = []
        self._threads: list[threading.Thread] = []

    @property
    def busy(self) -> str | None:
        """The running job's name, or None."""
        with self._lock:
            return self._names[-1] if self._names else None

    def start(self, name: str, fn: Callable[[], None]) -> bool:
        """Run ``fn`` on a new thread (False, nothing started, while another job runs)."""
        with self._lock:
            if self._names:
                return False
            self._names.append(name)
            self._cancel.clear()
        thread = threading.Thread(target=self._run, args=(fn,), name=f"job-{name}",
                                  daemon=True)
        self._threads = [t for t in self._threads if t.is_alive()] + [thread]
        self._on_busy(name)
        thread.start()
        return True

    def _run(self, fn: Callable[[], None]) -> None:
        try:
            fn()
        except Exception as exc:  # the job reports its own errors; a bug must not stop us
            self._on_error(exc)
        finally:
            self._done()

    @contextlib.contextmanager
    def running(self, name: str) -> Iterator[None]:
        """Mark a job running on the calling thread (the worker's fit)."""
        with self._lock:
            self._names.append(name)
            self._cancel.clear()
        self._on_busy(name)
        try:
            yield
        finally:
            self._done()

    def _done(self) -> None:
        with self._lock:
            self._names.pop()
            left = self._names[-1] if self._names else None
        self._on_busy(left)

    def cancel(self) -> None:
        """Ask the running job to stop at its next progress report."""
        self._cancel.set()

    def check(self) -> None:
        """Raise :class:`Cancelled` if *Cancel job* was pressed since the job started."""
        if self._cancel.is_set():
            raise Cancelled(by_user=True)

    def wait(self, timeout: float = 60.0) -> bool:
        """Wait for background jobs to end (tests, closing)."""
        for t in list(self._threads):
            t.join(timeout)
        return not any(t.is_alive() for t in self._threads)
