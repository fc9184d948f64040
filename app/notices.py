"""Notifications in every open page, one per cause: a newer one for the same cause replaces
the older, and a cause that is resolved (a design that solves again) clears its notice, so
late or superseded messages never pile up.

A design replaced by a load or a restore (a notice of cause :data:`LOAD` that is not an
error) clears every older error notice: they were about the design that is gone. Every
notice also closes the browser's own upload toasts ("Uploading x.json ... uploaded
successfully", which viser's upload button shows by itself), so a load gives one toast.
Texts pass :func:`app.wording.gui_text` (no command-line options in the page).
"""

from __future__ import annotations

import threading
from typing import Any

import viser
from viser import _messages

from app.wording import gui_text

#: The cause of "design loaded" / "changes restored" notices.
LOAD = "load"


class Notices:
    """Notifications of one studio; ``log`` keeps ``(title, body, error)`` for tests/logs."""

    def __init__(self, server: viser.ViserServer) -> None:
        self.server = server
        self.log: list[tuple[str, str, bool]] = []
        self._shown: dict[str, list[Any]] = {}  # cause -> notification handles (all pages)
        self._errors: set[str] = set()  # causes whose notice is an error
        self._uploads: list[tuple[Any, str]] = []  # (client id, toast id) of upload toasts
        self._lock = threading.Lock()
        websock = getattr(server, "_websock_server", None)
        if websock is not None:  # the upload toasts' ids (a viser detail: skipped if absent)
            websock.register_handler(_messages.FileTransferStartUpload, self._upload_started)

    def _upload_started(self, client_id: Any, message: Any) -> None:
        with self._lock:
            self._uploads.append((client_id, f"upload-{message.transfer_uuid}"))
            del self._uploads[:-20]

    def notify(self, title: str, body: str, error: bool = False, cause: str | None = None
               ) -> None:
        """Show ``title``/``body`` in every page, replacing the notice of the same ``cause``
        (default: the title). Errors stay 15 s, information 5 s."""
        title, body = gui_text(title), gui_text(body)
        with self._lock:
            self.log.append((title, body, error))
            del self.log[:-50]
            key = cause or title
            self._remove(key)
            if key == LOAD and not error:
                for old in list(self._errors):
                    self._remove(old)
            self._close_upload_toasts()
            clients = self.server.get_clients()
            self._shown[key] = [
                c.add_notification(title, body, color="red" if error else "blue",
                                   auto_close_seconds=15.0 if error else 5.0)
                for c in clients.values()]
            if error:
                self._errors.add(key)

    def clear(self, *causes: str) -> None:
        """Remove the notices of ``causes`` (their problem is gone)."""
        with self._lock:
            for cause in causes:
                self._remove(cause)

    def _remove(self, cause: str) -> None:
        self._errors.discard(cause)
        for handle in self._shown.pop(cause, []):
            try:
                handle.remove()
            except Exception:  # noqa: BLE001 - the page may have closed meanwhile
                pass

    def _close_upload_toasts(self) -> None:
        """Close the upload toasts shown so far (a finished upload's answer is ours)."""
        clients = self.server.get_clients()
        for client_id, toast in self._uploads:
            client = clients.get(client_id)
            if client is not None:
                client._websock_connection.queue_message(
                    _messages.RemoveNotificationMessage(toast))
        self._uploads = []
