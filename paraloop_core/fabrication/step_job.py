"""The STEP solids on the second core.

OpenCascade's booleans hold Python's lock, so a thread gains nothing: an export starts one
helper process when it starts (``python -m`` this module, in a session of its own, so a
Ctrl-C reaches only the export, which stops it; its imports overlap the sizing), hands it
the parts once they are built, before they are verified (:func:`printable.make`'s
``on_parts``), and collects ``parts.step`` and ``assembly.step`` after the meshes and the
guide are written. The helper evaluates the same trees with the same code
(:func:`step.step_files`), every other exact solid in a forked copy of itself (both cores
once the export's other files are written; :func:`_shared`); the parts' meshes travel as
float64 arrays (the :mod:`copyreg` reducer below). On one core, or when the helper fails
or dies, the solids are made here as before: the files never depend on it.
"""

from __future__ import annotations

import copyreg
import os
import pickle
import signal
import subprocess
import sys
import threading
from pathlib import Path
from types import SimpleNamespace

import manifold3d as m3d
import numpy as np

#: Seconds to wait for the helper's files after the rest of the export is done (it has
#: then had the parts since before their verification); past it they are made here.
WAIT_S = 300.0


def _manifold(vert_properties: np.ndarray, tri_verts: np.ndarray) -> m3d.Manifold:
    return m3d.Manifold(m3d.Mesh64(vert_properties=vert_properties, tri_verts=tri_verts))


def _reduce(man: m3d.Manifold) -> tuple:
    mesh = man.to_mesh64()
    return _manifold, (np.asarray(mesh.vert_properties, np.float64),
                       np.asarray(mesh.tri_verts, np.uint32))


copyreg.pickle(m3d.Manifold, _reduce)


def cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def _serve() -> None:
    """The helper: read one pickled job from stdin while OpenCascade loads, write the
    pickled ``(files, kinds)`` to stdout (exit 1 on any failure: the export makes them)."""
    data: list[bytes] = []
    reader = threading.Thread(target=lambda: data.append(sys.stdin.buffer.read()))
    reader.start()
    # the answer goes to the pipe's own descriptor; anything OpenCascade prints to stdout
    # goes where stderr goes (nowhere), not into the answer
    answer = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    from paraloop_core.fabrication import step

    reader.join()
    job, colors, steel = pickle.loads(data[0])
    made = _shared(step, step.exact_parts(job.parts)) if cores() >= 2 else None
    answer.write(pickle.dumps(step.step_files(job, colors, steel, made)))
    answer.close()


def _shared(step, parts: list) -> dict[int, tuple | None]:
    """:func:`step.tree_solid` of ``parts``, every other one made by a forked copy of this
    helper (OpenCascade loaded, the parts in memory): once the export has written its other
    files, both cores make solids. The copy's solids come back exact (binary BRep); where
    it fails, this process makes them (``part_solid`` finds them missing)."""
    theirs = parts[1::2]
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the copy: its share, then gone without running any exit handler
        os.close(read)
        try:
            out = []
            for p in theirs:
                made = step.tree_solid(p.csg, p.manifold.volume())
                out.append(None if made is None else (step.solid_bytes(made[0]), made[1]))
            with os.fdopen(write, "wb") as f:
                f.write(pickle.dumps(out))
        finally:
            os._exit(0)
    os.close(write)
    made = {id(p): step.tree_solid(p.csg, p.manifold.volume()) for p in parts[0::2]}
    with os.fdopen(read, "rb") as f:
        data = f.read()
    os.waitpid(pid, 0)
    try:
        for p, got in zip(theirs, pickle.loads(data), strict=True):
            made[id(p)] = None if got is None else (step.solid_from_bytes(got[0]), got[1])
    except (pickle.UnpicklingError, EOFError, ValueError):
        pass  # the copy failed: its parts are made by step_files
    return made


class StepJob:
    """``parts.step`` and ``assembly.step`` of an assembly, made by a helper process where
    there is a second core (module docstring). Use as a context manager: the helper is
    stopped on leaving it, whatever happened."""

    def __init__(self, spawn: bool | None = None) -> None:
        self._proc: subprocess.Popen | None = None
        self._sent = False
        self._out: list[bytes] = []
        self._reader: threading.Thread | None = None
        if spawn if spawn is not None else cores() >= 2:
            self._start()

    def _start(self) -> None:
        root = str(Path(__file__).resolve().parents[2])  # where paraloop_core lives
        env = {**os.environ, "PYTHONPATH": os.pathsep.join(
            [root, *filter(None, [os.environ.get("PYTHONPATH")])])}
        try:
            self._proc = subprocess.Popen(
                [sys.executable, "-m", __name__], stdin=subprocess.PIPE,
                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env,
                start_new_session=True)
        except OSError:  # no helper: made here
            self._proc = None
        self._out = []

    def __enter__(self) -> StepJob:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def submit(self, asm, colors: dict[str, np.ndarray], steel: np.ndarray) -> None:
        """Hand the helper the parts and hardware of ``asm`` (colours by part name). Parts
        handed again (they changed) go to a new helper: the first one is stopped."""
        if self._sent:
            self.close()
            self._start()
        if self._proc is None:
            return
        job = SimpleNamespace(parts=list(asm.parts), hardware=list(asm.hardware))
        try:
            self._proc.stdin.write(pickle.dumps((job, colors, steel)))
            self._proc.stdin.close()
            self._sent = True
        except OSError:  # the helper is gone: made here
            self.close()
            return
        # its answer is drained as it comes (a full pipe would stall the helper)
        stdout = self._proc.stdout
        self._reader = threading.Thread(target=lambda: self._out.append(stdout.read()),
                                        daemon=True)
        self._reader.start()

    def withdraw(self) -> None:
        """The parts handed are not kept (rebuilt without a keel): their helper is stopped
        (its solids took the core the rebuild runs on; each verification uses both) and a
        new one loads OpenCascade meanwhile, for the next parts handed."""
        if self._sent:
            self.close()
            self._start()

    def result(self, asm, colors: dict[str, np.ndarray], steel: np.ndarray
               ) -> tuple[list[tuple[str, bytes]], dict[str, str]]:
        """``(files, kinds)`` of :func:`step.step_files` for ``asm``: the helper's when it
        made them, else made here."""
        if self._sent:
            self._reader.join(WAIT_S)
            if self._out and self._proc.wait() == 0:
                try:
                    return pickle.loads(self._out[0])
                except (pickle.UnpicklingError, EOFError, ValueError):
                    pass
        self.close()
        from paraloop_core.fabrication import step  # OpenCascade: loaded only to write STEP

        return step.step_files(asm, colors, steel)

    def close(self) -> None:
        """Stop the helper (it holds nothing worth keeping once this is asked)."""
        if self._proc is not None:
            if self._proc.poll() is None:
                # its session: the helper and the copy it forked (which holds the answer's
                # pipe open: closing it would wait for that copy's solids, made for nothing)
                try:
                    os.killpg(self._proc.pid, signal.SIGKILL)
                except (AttributeError, OSError):  # no process groups: the helper alone
                    self._proc.kill()
            self._proc.wait()
            for pipe in (self._proc.stdin, self._proc.stdout):
                pipe.close()
            self._proc = None
        self._sent = False


if __name__ == "__main__":
    _serve()
