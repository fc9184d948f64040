"""What the studio's panels may ask of the studio: a narrow interface below both.

Panels hold a :class:`StudioHost` (the :class:`app.studio.Studio` satisfies it) and never import
the studio module, so ``app.panels`` sits strictly below ``app.studio`` (checked by import-linter).
"""

from __future__ import annotations

from typing import Any, Protocol

import viser

from app.jobs import Jobs
from app.scene import SceneView
from app.state import StudioState
from paraloop_core.pipeline import Solution


class StudioHost(Protocol):
    """The studio as its panels see it: state, the worker, notifications and file transfers."""

    server: viser.ViserServer
    state: StudioState
    scene: SceneView
    jobs: Jobs  # long jobs (fit, carve, export) and *Cancel job*
    solution: Solution | None  # last valid solution (on screen)
    error: str | None  # why the current design has no solution

    def request(self, level: int, sync: bool = False) -> None:
        """Ask the worker for an update of ``level`` (``app.worker`` FRAME/PREVIEW/FULL)."""

    def notify(self, title: str, body: str, error: bool = False, cause: str | None = None
               ) -> None:
        """Show a notification in every connected browser (one per ``cause``)."""

    def send_file(self, client: Any, name: str, data: bytes) -> None:
        """Send a download to one browser client."""

    def panels_order(self) -> float:
        """GUI order of the status line (offers are placed just below it)."""

    def reframe(self) -> None:
        """Frame the camera after the next full update."""

    def show_layer(self, name: str) -> None:
        """Switch a scene layer on and tick its View or Construction checkbox (worker)."""

    def download_design(self, event: Any) -> None:
        """*Save design*: the current design file to the clicking browser."""

    def download_export(self, event: Any) -> None:
        """*Download result*: queue the result files for the clicking browser."""

    def download_animation(self, event: Any) -> None:
        """*Animation*: queue the realized loop as an animated glTF for the clicking browser."""

    def upload_design(self, event: Any) -> None:
        """*Load design*: replace the design with an uploaded file."""
