"""Shared boundary code of the command line: output paths checked before any work starts,
all-or-nothing writes (temporary files + rename, nothing left on failure), argparse types with
clear ranges, one-line messages and the exit codes of ``docs/result-format.md``.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import tempfile
import threading
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

from paraloop_core.errors import ParaloopError

#: exit codes (docs/result-format.md, "Command line")
EXIT_OK, EXIT_INTERNAL, EXIT_REFUSED, EXIT_NOT_REALIZED, EXIT_INTERRUPTED = 0, 1, 2, 3, 130
REPORT = "please report it with the input file to the paraloop issue tracker"


class OutputError(ParaloopError):
    """An output path cannot be used (exists without --force, not a directory, not writable)."""

    reason = "output"


def one_line(exc: BaseException | str, limit: int = 400) -> str:
    """The message on one line, bounded (error messages may quote user input)."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def int_range(lo: int, hi: int) -> Callable[[str], int]:
    """argparse type: a decimal integer in ``lo..hi``."""

    def parse(text: str) -> int:
        try:
            value = int(text, 10)
        except ValueError:
            value = None
        if value is None or not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"must be an integer in {lo}..{hi}, got {text!r}")
        return value

    return parse


def float_range(lo: float, hi: float, *, lo_open: bool = False) -> Callable[[str], float]:
    """argparse type: a finite number in ``[lo, hi]`` (``(lo, hi]`` with ``lo_open``)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if not (value > lo if lo_open else value >= lo) or not value <= hi:
            raise argparse.ArgumentTypeError(
                f"must be a number in {'(' if lo_open else '['}{lo:g}, {hi:g}], got {text!r}")
        return value

    return parse


def output_path(text: str, option: str) -> Path:
    """The path of an output option (``-o``, ``--out``); an empty one is refused (it would
    mean the current folder without saying so)."""
    if not text:
        raise OutputError(f"{option}: an empty path is not an output (give a folder or file "
                          "name; '.' for the current folder)")
    return Path(text)


def _writable_dir(d: Path) -> None:
    """``d`` (existing) must be a directory where a file can be written, a missing one
    creatable: a probe file is written and removed in it (or in its nearest existing parent),
    the one test that holds everywhere (as root, ``os.access`` says yes to /proc and /sys)."""
    probe = d
    try:
        while not probe.exists() and probe != probe.parent:
            if probe.is_symlink():
                raise OutputError(f"{probe}: dangling symbolic link in the output path")
            probe = probe.parent
        if not probe.is_dir():
            raise OutputError(f"{probe}: exists and is not a directory")
        fd, tmp = tempfile.mkstemp(prefix=".paraloop-probe.", suffix=".tmp", dir=probe)
    except OSError as exc:
        raise OutputError(f"{one_line(str(probe), 200)}: cannot write there "
                          f"({exc.strerror or exc})") from exc
    try:
        os.write(fd, b"\n")
    except OSError as exc:
        raise OutputError(f"{probe}: cannot write there ({exc.strerror or exc})") from exc
    finally:
        os.close(fd)
        os.unlink(tmp)


def check_file_target(path: Path, force: bool) -> None:
    """``path`` can be written: not a directory, absent (or ``force``), in a writable folder."""
    try:
        if path.is_dir():
            raise OutputError(f"{path}: is a directory (give a file name)")
        if path.exists() or path.is_symlink():
            if not path.is_file():
                raise OutputError(f"{path}: exists and is not a regular file")
            if not force:
                raise OutputError(f"{path}: already exists (use --force to overwrite)")
    except OSError as exc:  # e.g. a name too long
        raise OutputError(f"{one_line(str(path), 200)}: cannot use it ({exc.strerror or exc})"
                          ) from exc
    _writable_dir(path.parent)


def check_dir_target(out: Path, names: Iterable[str], force: bool) -> None:
    """``out`` is (or can become) a writable directory and none of ``names`` in it exists
    (unless ``force``)."""
    try:
        if out.exists() and not out.is_dir():
            raise OutputError(f"{out}: exists and is not a directory")
    except OSError as exc:
        raise OutputError(f"{one_line(str(out), 200)}: cannot use it ({exc.strerror or exc})"
                          ) from exc
    _writable_dir(out)
    if out.is_dir():
        for name in names:
            check_file_target(out / name, force)


def check_not_inputs(targets: Iterable[Path], inputs: Iterable[Path]) -> None:
    """Refuse an output that would overwrite one of the input files."""
    ins = {_key(p): p for p in inputs}
    for t in targets:
        if _key(t) in ins:
            raise OutputError(f"{t}: would overwrite the input {ins[_key(t)]}")


def _key(p: Path) -> str:
    try:
        return os.path.normcase(str(p.resolve()))
    except (OSError, RuntimeError):
        return os.path.normcase(os.path.abspath(p))


def check_distinct(targets: list[Path], inputs: list[Path]) -> None:
    """Refuse two inputs that would write the same output file."""
    seen: dict[str, Path] = {}
    for t, src in zip(targets, inputs, strict=True):
        k = _key(t)
        if k in seen:
            what = ("is given twice" if _key(seen[k]) == _key(src)
                    else f"and {seen[k]} would both write {t}")
            raise OutputError(f"{src} {what}; rename one or solve them into separate folders")
        seen[k] = src


@contextlib.contextmanager
def created_dir(out: Path) -> Iterator[Path]:
    """Create ``out`` (and parents) if missing; remove what was created if the block fails and
    left it empty."""
    missing = []
    probe = out
    while not probe.exists() and probe != probe.parent:
        missing.append(probe)
        probe = probe.parent
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{out}: cannot create the directory ({exc.strerror or exc})") from exc
    try:
        yield out
    except BaseException as exc:
        seen(exc)
        for d in missing:  # deepest first
            with contextlib.suppress(OSError):
                d.rmdir()
        raise


def write_files(out: Path, files: Iterable[tuple[str, bytes]]) -> None:
    """All of ``files`` into ``out`` or none: each is written to a temporary file there (with
    the umask's mode), then all are renamed; on failure the temporaries are removed."""
    from paraloop_core.result import temp_file  # numpy and the algebra: not for --help

    with created_dir(out):
        staged: list[tuple[str, Path]] = []
        try:
            for name, data in files:
                fd, tmp = temp_file(out, name)
                staged.append((name, tmp))
                with os.fdopen(fd, "wb") as fh:
                    fh.write(data)
            for name, tmp in staged:
                os.replace(tmp, out / name)
        except BaseException as exc:
            seen(exc)
            for _, tmp in staged:
                tmp.unlink(missing_ok=True)
            raise


@contextlib.contextmanager
def staged_dir(out: Path) -> Iterator[Path]:
    """A temporary folder inside ``out`` for writers that take a path (plots, CSV): on success
    its files are moved into ``out``, on failure it is deleted."""
    with created_dir(out), tempfile.TemporaryDirectory(prefix=".staging.", dir=out) as tmp:
        yield Path(tmp)
        for f in sorted(Path(tmp).iterdir()):
            os.replace(f, out / f.name)


def add_seed(p: argparse.ArgumentParser, seed_help: str) -> None:
    """The ``--seed`` option shared by the ``validate`` commands."""
    p.add_argument("--seed", type=int_range(0, 2**32 - 1), default=0,
                   help=f"{seed_help} (0..2^32-1)")


def draw_bar(fill: float, text: str, width: int = 30) -> None:
    """A progress bar on stderr, ``[#####.....] text``, redrawn in place; ``fill`` in [0, 1]
    (a new line once it is full)."""
    n = min(int(width * fill), width)
    sys.stderr.write(f"\r[{'#' * n}{'.' * (width - n)}] {text}")
    if fill >= 1.0:
        sys.stderr.write("\n")
    sys.stderr.flush()


# --- Ctrl-C -------------------------------------------------------------------------------------
#: seconds between repeats of an interrupt that nothing has caught yet
INTERRUPT_REPEAT = 0.25


class _Interrupts:
    """Ctrl-C ends a run at any moment with exit 130 and one line. SIGINT raises
    KeyboardInterrupt and, until the command line's code sees it propagate (:func:`seen`),
    raises it again every :data:`INTERRUPT_REPEAT` seconds (SIGALRM): some libraries swallow
    BaseException (trimesh's optional imports), which once made 7 of 20 Ctrl-C presses
    vanish. Further SIGINTs are ignored while one is pending (the repeats carry it)."""

    def __init__(self) -> None:
        self.pending = self.repeating = False
        self.saved: list[tuple[int, Any]] = []

    def install(self) -> None:
        if threading.current_thread() is not threading.main_thread():
            return  # signals are the main thread's
        self.pending = self.repeating = False
        for sig in (signal.SIGINT, getattr(signal, "SIGALRM", None)):
            if sig is not None:
                self.saved.append((sig, signal.signal(sig, self._handle)))

    def _handle(self, signum: int, frame: Any) -> None:
        if signum == signal.SIGINT:
            if self.pending:
                return
            self.pending = self.repeating = True
            if hasattr(signal, "setitimer"):
                signal.setitimer(signal.ITIMER_REAL, INTERRUPT_REPEAT, INTERRUPT_REPEAT)
        elif not self.repeating:  # an alarm already on its way when the repeats stopped
            return
        raise KeyboardInterrupt

    def seen(self) -> None:
        if self.repeating and hasattr(signal, "setitimer"):
            signal.setitimer(signal.ITIMER_REAL, 0.0)
        self.repeating = False

    def restore(self) -> None:
        self.seen()
        while self.saved:
            signal.signal(*self.saved.pop())


_INTERRUPTS = _Interrupts()
catch_interrupts, restore_interrupts = _INTERRUPTS.install, _INTERRUPTS.restore


def check_interrupt() -> None:
    """Raise KeyboardInterrupt when a Ctrl-C is pending: an error seen after one (a library
    that swallowed it left a module half imported) is its consequence, not a bug or bad input."""
    if _INTERRUPTS.pending:
        raise KeyboardInterrupt


def seen(exc: BaseException | None) -> None:
    """Called by code unwinding for ``exc``: when it is a Ctrl-C, the interrupt is
    propagating, so it is not repeated (a clean-up that takes time, e.g. closing a Dask
    cluster, is not cut short)."""
    if isinstance(exc, KeyboardInterrupt):
        _INTERRUPTS.seen()


def internal_error(where: str, exc: BaseException, debug: bool) -> int:
    """One line for an unexpected exception (a bug); the traceback only with ``--debug``
    (after a Ctrl-C: KeyboardInterrupt, see :func:`check_interrupt`)."""
    check_interrupt()
    print(f"error: {where}internal error ({type(exc).__name__}: {one_line(exc, 200)}); "
          f"{REPORT} (rerun with --debug for the traceback)", file=sys.stderr)
    if debug:
        import traceback

        traceback.print_exception(exc)
    return EXIT_INTERNAL
