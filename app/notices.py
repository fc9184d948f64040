"""Notifications in every open page, one per cause: a newer one for the same cause replaces
the older, and a cause that is resolved (a design that solves again) clears its notice, so
late or superseded messages never pile up."""

from __future__ import annotations

import threading
from typing import Any

import viser


class Notices:
    """Notifications of one studio; ``log`` keeps ``(title, body, error)`` for tests/logs."""

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self.log: list[tuple[str, str, bool]] = []
        self._shown: dict[str, list[Any]] = {}  # cause -> notification handles (all pages)
        self._lock = threading.Lock()

    def notify(self, title: str, body: str, error: bool = False, cause: str | None = None
               ) -> None:
        """Show ``title``/``body`` in every page, replacing the notice of the same ``cause``
        (default: the title). Errors stay 15 s, information 5 s."""
        with self._lock:
            self.log.append((title, body, error))
            del self.log[:-50]
            key = cause or title
            self._remove(key)
            self._shown[key] = [
                c.add_notification(title, body, color="red" if error else "blue",
                                   auto_close_seconds=15.0 if error else 5.0)
                for c in self.server.get_clients().values()]

    def clear(self, *causes: str) -> None:
        """Remove the notices of ``causes`` (their problem is gone)."""
        with self._lock:
            for cause in causes:
                self._remove(cause)

    def _remove(self, cause: str) -> None:
        for handle in self._shown.pop(cause, []):
            try:
                handle.remove()
            except Exception:  # noqa: BLE001 - the page may have closed meanwhile
                pass
