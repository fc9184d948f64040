"""The studio's file transfers: *Save design*, *Export result* and *Animation* downloads (the
last two built on the worker: queued tasks) and *Load design* uploads (a mixin of
:class:`app.studio.Studio`, which supplies the state, the solution, notifications and update
requests)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from app.exports import animation_file, export_files, slug
from app.state import StudioState, autosave_path_for, portable_mesh, uploaded_meshes_dir
from app.worker import FRAME, FULL
from paraloop_core import design as design_mod
from paraloop_core import pipeline
from paraloop_core.errors import DesignFileError, ParaloopError

EXAMPLES = Path(__file__).resolve().parent.parent / "assets" / "designs"


def studio_design(design: design_mod.Design) -> design_mod.Design:
    """``design`` when the studio can show it; a Bennett design (three poses) is refused with
    DesignFileError: its panels, drawing and realization are written for 6R loops
    (``paraloop solve`` gives its motion, factorizations and loop axes)."""
    if design.linkage == "bennett":
        raise DesignFileError("linkage", "the studio does not show Bennett linkages (three "
                              "poses) yet; solve the design with 'paraloop solve'")
    return design


class FileTransfers:
    """Downloads (kept in ``downloads``, the last 10) and design uploads; the host class
    supplies the attributes below and ``notify``, ``reframe`` and ``request``."""

    state: StudioState
    solution: pipeline.Solution | None
    error: str | None
    downloads: list[tuple[str, bytes]]

    def send_file(self, client: Any, name: str, data: bytes) -> None:
        """Download ``data`` as ``name`` in ``client``'s page (kept in ``downloads``)."""
        self.downloads.append((name, data))
        del self.downloads[:-10]
        if client is not None:
            client.send_file_download(name, data, save_immediately=True)

    def download_design(self, event: Any) -> None:
        design = self.state.design
        data = json.dumps(design_mod.design_to_dict(portable_mesh(design)), indent=2) + "\n"
        self.send_file(event.client, f"{slug(design.name)}.json", data.encode("utf-8"))

    def download_export(self, event: Any) -> None:
        self.state.add_task("result", event.client)  # built on the worker: the result JSON
        self.request(FRAME)  # plans the drive (20 - 400 ms), too much for a callback

    def download_animation(self, event: Any) -> None:
        self.state.add_task("animation", event.client)  # meshes, plan, 240 frames: the worker
        self.request(FRAME)

    def send_download(self, task: str, client: Any) -> None:
        """Build and send a queued ``result`` or ``animation`` download (worker thread)."""
        sol = self.solution
        try:
            if sol is None:
                raise ValueError(self.error or "no solution yet")
            if task == "result":
                if self.error:
                    self.notify("Exporting the last valid design", self.error, error=True)
                files = export_files(sol)
            else:
                files = [animation_file(sol)]
        except ValueError as exc:
            what = "Nothing to export" if task == "result" else "Nothing to animate"
            self.notify(what, str(exc), error=True)
            return
        for name, data in files:
            self.send_file(client, name, data)

    def upload_design(self, event: Any) -> None:
        """*Load design*: the uploaded bytes through the core loader (the command line's, with
        its limits; an oversized upload is refused before it is decoded); a relative mesh path
        refers to the opened design's folder (a browser does not tell the file's), else to a
        bundled or uploaded mesh of that name. Every failure is one notification; the design
        is then unchanged."""
        upload = event.target.value
        name = slug(Path(upload.name).stem)[:60] or "design"
        try:
            design = studio_design(design_mod.load_design_bytes(
                upload.content, base_dir=self.state.design.base_dir or str(EXAMPLES),
                mesh_dirs=(str(uploaded_meshes_dir()),)))
        except ParaloopError as exc:
            self._refuse(upload.name, str(exc))
            return
        except Exception as exc:  # a bug: still one message in the page, not a silent failure
            self._refuse(upload.name, f"internal error ({type(exc).__name__}: {exc})"[:300])
            return
        # its own autosave, keyed by content: the opened file's one keeps that file's work
        key = hashlib.sha256(upload.content).hexdigest()[:12]
        self.state.autosave_path = autosave_path_for(None, f"upload-{name}-{key}")
        self.state.commit(design)
        self.reframe()
        self.request(FULL, sync=True)
        self.notify("Design loaded", upload.name[:200], cause="load")

    def _refuse(self, file_name: str, message: str) -> None:
        self.notify(f"Cannot load {file_name[:80]}", f"{message} (the design is unchanged)",
                    error=True, cause="load")
