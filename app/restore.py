"""The offer to restore unsaved changes: on start, an autosave newer than the opened file is
not applied silently; the panel shows *Restore changes from HH:MM* and *Discard changes*."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING

import viser

from app.state import absolute_mesh, uploaded_meshes_dir
from app.worker import FULL
from paraloop_core import design as design_mod
from paraloop_core.design import Design
from paraloop_core.errors import DesignFileError

if TYPE_CHECKING:
    from app.host import StudioHost


def newer_autosave(autosave: Path | None, design_path: Path | None,
                   base_dir: str | None = None) -> tuple[Design, float] | str | None:
    """The autosaved design and its time when it is newer than ``design_path`` (any autosave
    when no file was opened), a message when it is unreadable, else None. It is loaded as the
    opened design is, against ``base_dir`` (the opened design's folder) and the uploaded
    meshes: a mesh path that does not resolve there is refused, never restored broken."""
    try:
        if autosave is None or not autosave.exists():
            return None
        mtime = autosave.stat().st_mtime
        if design_path is not None and mtime <= design_path.stat().st_mtime:
            return None
    except OSError as exc:
        return f"ignored the autosave {autosave}: {exc}"
    folder = base_dir or str(design_path.resolve().parent if design_path else autosave.parent)
    try:
        return design_mod.load_design(autosave, (str(uploaded_meshes_dir()),), folder), mtime
    except DesignFileError as exc:
        return f"ignored a broken autosave {autosave}: {exc}"


class RestoreOffer:
    """Buttons under the status line; *Restore* commits the autosaved design (the opened
    file's version stays one Undo away), *Discard* deletes the autosave."""

    def __init__(self, studio: StudioHost, design: Design, mtime: float) -> None:
        self.studio = studio
        self.design = design  # kept in memory: later autosaves cannot lose it
        gui, order = studio.server.gui, studio.panels_order() + 0.01
        when = time.strftime("%H:%M", time.localtime(mtime))
        day = time.strftime("%Y-%m-%d", time.localtime(mtime))
        self.text = gui.add_markdown(
            f"**Unsaved changes** from {day} {when} were found (autosave).", order=order)
        self.restore = gui.add_button(f"Restore changes from {when}", icon=viser.Icon.RESTORE,
                                      color="green", order=order + 0.001,
                                      hint="replace the opened file's design by the autosave "
                                           "(Undo returns to the file)")
        self.discard = gui.add_button("Discard changes", order=order + 0.002,
                                      hint="keep the opened file and delete the autosave")
        self.restore.on_click(lambda _: self.accept())
        self.discard.on_click(lambda _: self.reject())
        self.open = True

    def accept(self) -> None:
        if not self._close():
            return
        self.studio.state.commit(self.design)
        self.studio.reframe()
        self.studio.request(FULL, sync=True)
        self.studio.notify("Changes restored", "Undo returns to the opened file", cause="load")

    def reject(self) -> None:
        if not self._close():
            return
        path = self.studio.state.autosave_path
        if path is not None and self.studio.state.version == 0:  # nothing newer written
            path.unlink(missing_ok=True)
        self.studio.notify("Changes discarded", "the opened file is kept", cause="load")

    def _close(self) -> bool:
        if not self.open:
            return False
        self.open = False
        for handle in (self.text, self.restore, self.discard):
            handle.remove()
        return True


def offer_restore(studio: StudioHost, design_path: Path | None) -> str | None:
    """Offer the autosave when it is newer than the opened file (``studio.restore_offer``);
    returns a line for the terminal, or None."""
    found = newer_autosave(studio.state.autosave_path, design_path, studio.state.design.base_dir)
    if found is None or isinstance(found, str):
        return found
    design, mtime = found
    same = design_mod.design_to_dict(absolute_mesh(design))
    if same == design_mod.design_to_dict(absolute_mesh(studio.state.design)):
        return None  # nothing unsaved: the edits were undone before the autosave
    studio.restore_offer = RestoreOffer(studio, design, mtime)
    return (f"unsaved changes from {time.strftime('%H:%M', time.localtime(mtime))} found in "
            f"{studio.state.autosave_path}: the page offers to restore them")
