"""The studio's plain state: the design being edited, undo/redo history and autosave.

UI handlers only call the methods here (cheap, lock-protected); the worker reads snapshots.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import shutil
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import platformdirs

from paraloop_core import design as design_mod
from paraloop_core.design import Design, Pose
from paraloop_core.errors import DesignFileError

HISTORY = 200
MERGE_SECONDS = 1.5


def user_data_dir() -> Path:
    """The user data folder (uploaded meshes): ``$XDG_DATA_HOME/paraloop`` or
    ``~/.local/share/paraloop``."""
    return Path(os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share") / "paraloop"


def autosave_dir() -> Path:
    """Where autosaves live: the user *state* folder (platformdirs ``user_state_dir``, on
    Linux ``$XDG_STATE_HOME/paraloop`` or ``~/.local/state/paraloop``), ``autosave/``."""
    return Path(platformdirs.user_state_dir("paraloop")) / "autosave"


def legacy_autosave_dir() -> Path:
    """Where autosaves lived before they moved to :func:`autosave_dir` (the data folder)."""
    return user_data_dir() / "autosave"


def autosave_path_for(design_path: Path | None, name: str) -> Path:
    """The autosave file in :func:`autosave_dir`, never beside the design (a repository or a
    read-only folder stays clean): ``<stem>-<hash of the resolved path>.json`` for an opened
    file, so two files with one name or one design name never share it, else
    ``<name>.json``."""
    folder = autosave_dir()
    if design_path is not None:
        key = hashlib.sha1(str(Path(design_path).resolve()).encode()).hexdigest()[:12]
        return folder / f"{_safe(Path(design_path).stem)}-{key}.json"
    return folder / f"{_safe(name)}.json"


def migrate_autosave(path: Path) -> bool:
    """Move an autosave of the same name from :func:`legacy_autosave_dir` to ``path`` when
    ``path`` has none (its time kept, so the restore offer compares it with the design file
    as before). True if one was moved."""
    old = legacy_autosave_dir() / path.name
    if path.exists() or not old.is_file():
        return False
    path.parent.mkdir(parents=True, exist_ok=True)
    shutil.move(str(old), str(path))
    return True


def _safe(text: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in text) or "untitled"


def absolute_mesh(design: Design) -> Design:
    """``design`` with its end-effector mesh path as the file it stands for (absolute), for
    comparing designs and keying caches: one string per mesh file."""
    ee = design.end_effector
    if ee is None or ee.mesh is None:
        return design
    try:
        mesh = design_mod.mesh_file(design)
    except DesignFileError:  # no such mesh: the path as written is the key
        mesh = ee.mesh
    if mesh == ee.mesh:
        return design
    return dataclasses.replace(design, end_effector=dataclasses.replace(ee, mesh=mesh))


def portable_mesh(design: Design) -> Design:
    """``design`` as a file to save or download: an absolute mesh path (an uploaded mesh)
    becomes its file name, which the loader finds among the uploaded meshes; no server path
    leaves the studio. A relative path stays: it refers to the design's folder."""
    ee = design.end_effector
    if ee is None or ee.mesh is None or not Path(ee.mesh).is_absolute():
        return design
    return dataclasses.replace(design, end_effector=dataclasses.replace(
        ee, mesh=Path(ee.mesh).name))


def uploaded_meshes_dir() -> Path:
    """Where the studio keeps uploaded meshes (``meshes/<name>-<hash>.<ext>``, keyed by
    content) in the user data folder; designs find them by file name."""
    return user_data_dir() / "meshes"


def with_uploads(design: Design) -> Design:
    """``design`` finding its mesh among the uploaded ones too (``Design.mesh_dirs``)."""
    folder = str(uploaded_meshes_dir())
    if folder in design.mesh_dirs:
        return design
    return dataclasses.replace(design, mesh_dirs=(*design.mesh_dirs, folder))


def rescaled(design: Design, factor: float) -> Design:
    """``design`` with every length times ``factor`` (a change of unit): target positions,
    extra poses and target points, the inertia ellipsoid, realization lengths and the
    end-effector's scale and clearance; rotations and unit-free settings stay."""
    f = float(factor)

    def pose(p: Pose) -> Pose:
        return Pose(p.position * f, p.wxyz.copy())

    m, i, r, ee = design.motion, design.inertia, design.realization, design.end_effector
    motion = dataclasses.replace(m, targets=None if m.targets is None else m.targets * f,
                                 extra_poses=tuple(pose(p) for p in m.extra_poses))
    inertia = dataclasses.replace(i, center=i.center * f, semi_axes=i.semi_axes * f)
    real = dataclasses.replace(r, rho=None if r.rho is None else r.rho * f,
                               d=None if r.d is None else r.d * f,
                               fixed={k: v * f for k, v in r.fixed.items()})
    if ee is not None:
        ee = dataclasses.replace(ee, scale=ee.scale * f, clearance=None if ee.clearance is None
                                 else ee.clearance * f)
    return dataclasses.replace(design, poses=tuple(pose(p) for p in design.poses),
                               motion=motion, inertia=inertia, realization=real,
                               end_effector=ee)


@dataclasses.dataclass(frozen=True)
class FabSettings:
    """Fabrication panel settings (validated by the panel): part size (0: automatic, the
    largest at which the parts fit the printer's bed), the printer profile and its build
    volume ``"X,Y,Z"`` in mm (empty: the profile's), clearance in mm, the grounding
    column and its link (None: the best), carving radius in mm (0: the realization's median
    design-space radius), voxels along a space (0: automatic,
    :func:`voxelspace.auto_resolution`), the carving
    order (a preset name or ``custom``) and its custom pairs text."""

    size_mm: float = 0.0
    printer: str = "generic"
    bed: str = ""
    clearance_mm: float = 0.3
    print_in_place: bool = False
    ground: bool = True
    ground_link: int | None = None
    space_radius_mm: float = 0.0
    resolution: int = 0
    order: str = "base first"
    custom_order: str = ""
    carved_parts: bool = False


class StudioState:
    """Current design (``design``), the last committed one, history and animation settings.

    ``preview`` changes the design without history (during a drag); ``commit`` records an
    undoable edit. ``version`` increases on every change so the worker can tell what is new.
    """

    def __init__(self, design: Design, autosave_path: Path | None = None) -> None:
        self._lock = threading.RLock()
        self._edited = threading.Condition(self._lock)  # wakes the autosave
        self.design = design
        self.committed = design
        self.undo_stack: list[Design] = []
        self.redo_stack: list[Design] = []
        self.version = 0
        self.saved_version = 0
        self.autosave_path = autosave_path
        self.u = 0.0  # animation parameter in [0, 1]
        self.playing = False
        self.speed = 0.1  # cycles per second
        self.hidden: set[str] = set()  # view layers switched off
        self.thickness = 1.0  # bars drawn this many times their radius
        self.fab = FabSettings()
        self.tasks: dict[str, Any] = {}  # worker task ("carve", "export", "mesh") -> argument
        self.last_moved: int | None = None  # the target the last edit dragged (advice)
        self._merge_key: str | None = None
        self._merge_time = 0.0

    # --- edits ------------------------------------------------------------------------------
    def preview(self, design: Design) -> None:
        """Show ``design`` now; the edit becomes undoable at the next :meth:`commit`."""
        with self._lock:
            self.design = design
            self._changed()

    def commit(self, design: Design | None = None, merge: str | None = None) -> None:
        """Record ``design`` (default: the previewed one) as one undoable edit; edits with the
        same ``merge`` key within ``MERGE_SECONDS`` (a slider being dragged) become one."""
        with self._lock:
            design = self.design if design is None else design
            now = time.monotonic()
            merged = (merge is not None and merge == self._merge_key
                      and now - self._merge_time < MERGE_SECONDS and bool(self.undo_stack))
            if not merged:
                self.undo_stack.append(self.committed)
                del self.undo_stack[:-HISTORY]
            self._merge_key, self._merge_time = merge, now
            self.redo_stack.clear()
            self.design = self.committed = design
            self._changed()

    def edit(self, change: Callable[[Design], Design], merge: str | None = None) -> None:
        """Commit ``change(current design)`` atomically (see :meth:`commit` for ``merge``)."""
        with self._lock:
            self.commit(change(self.design), merge=merge)

    def _changed(self) -> None:
        """A new version (called holding the lock): wakes :meth:`wait_unsaved`; the pose
        edits set :attr:`last_moved` after it."""
        self.version += 1
        self.last_moved = None
        self._edited.notify_all()

    def undo(self) -> bool:
        with self._lock:
            if not self.undo_stack:
                return False
            self.redo_stack.append(self.committed)
            self._merge_key = None
            self.design = self.committed = self.undo_stack.pop()
            self._changed()
            return True

    def redo(self) -> bool:
        with self._lock:
            if not self.redo_stack:
                return False
            self.undo_stack.append(self.committed)
            self._merge_key = None
            self.design = self.committed = self.redo_stack.pop()
            self._changed()
            return True

    def snapshot(self) -> tuple[Design, int]:
        """The current design and its version."""
        with self._lock:
            return self.design, self.version

    # --- pose edits -------------------------------------------------------------------------
    def move_pose(self, i: int, position: np.ndarray, wxyz: np.ndarray, commit: bool) -> bool:
        """Move target ``i`` (ignored and False when locked)."""
        with self._lock:
            d = self.design
            if i in d.locked or not 0 <= i < len(d.poses):
                return False
            pose = Pose(np.asarray(position, float).copy(), np.asarray(wxyz, float).copy())
            new = dataclasses.replace(d, poses=d.poses[:i] + (pose,) + d.poses[i + 1 :])
            (self.commit if commit else self.preview)(new)
            self.last_moved = i
            return True

    def set_locked(self, i: int, locked: bool) -> bool:
        """Lock or unlock pose ``i``; at least one pose stays free. False if refused."""
        with self._lock:
            d = self.design
            new = set(d.locked) | {i} if locked else set(d.locked) - {i}
            if len(new) >= len(d.poses) or new == set(d.locked):
                return False
            self.commit(dataclasses.replace(d, locked=tuple(sorted(new))))
            return True

    def add_pose(self, pose: Pose) -> None:
        with self._lock:
            self.commit(dataclasses.replace(self.design, poses=self.design.poses + (pose,)))
            self.last_moved = len(self.design.poses) - 1

    def remove_pose(self, i: int) -> bool:
        """Remove target ``i``; lock indices are renumbered. False if out of range or only four
        targets are left (every design needs at least four)."""
        with self._lock:
            d = self.design
            if not 0 <= i < len(d.poses) or len(d.poses) <= 4:
                return False
            locked = tuple(j - (j > i) for j in d.locked if j != i)
            self.commit(dataclasses.replace(d, poses=d.poses[:i] + d.poses[i + 1 :],
                                            locked=locked))
            return True

    # --- worker tasks -----------------------------------------------------------------------
    def add_task(self, name: str, arg: Any = None) -> None:
        """Queue a task for the worker (asked twice: runs once, with the last ``arg``: the
        client who gets a fabrication download, an uploaded mesh's (name, content))."""
        with self._lock:
            self.tasks.pop(name, None)
            self.tasks[name] = arg

    def take_tasks(self) -> list[tuple[str, Any]]:
        """The queued ``(task, arg)``, oldest first; the queue is emptied."""
        with self._lock:
            out, self.tasks = list(self.tasks.items()), {}
            return out

    # --- autosave ---------------------------------------------------------------------------
    def wait_unsaved(self, timeout: float) -> bool:
        """Block until the design differs from the last autosave (an edit, a drag step), at
        most ``timeout`` seconds; whether it does. Independent of the worker: the design is
        the state, a running search does not delay it."""
        with self._edited:
            return self._edited.wait_for(
                lambda: self.autosave_path is not None and self.saved_version != self.version,
                timeout)

    def keep_saved(self, stop: threading.Event, failed: Callable[[OSError], None],
                   gap: float) -> None:
        """The autosave loop (a thread of its own, until ``stop``): each change is written at
        once, further ones at most every ``gap`` seconds; ``failed`` hears of write errors."""
        while not stop.is_set():
            if self.wait_unsaved(0.5) and not stop.is_set():
                try:
                    self.autosave()
                except OSError as exc:
                    failed(exc)
                stop.wait(gap)

    def autosave(self) -> bool:
        """Write the current design (an unfinished drag included) to the autosave file if it
        changed since the last write."""
        with self._lock:
            if self.autosave_path is None or self.saved_version == self.version:
                return False
            design, version = self.design, self.version
        self.autosave_path.parent.mkdir(parents=True, exist_ok=True)
        # a restore loads it against the opened design's folder and the uploaded meshes
        design_mod.save_design(portable_mesh(design), self.autosave_path)
        self.saved_version = version
        return True
