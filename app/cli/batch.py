"""Independent tasks of ``paraloop solve`` and ``paraloop validate``, run in this process, on a
local Dask cluster (``--workers N``) or on a running one (``--dask ADDRESS``).

Results come back in input order and equal those of a run in one process: tasks are pure and
their seeds never depend on the worker. An exception raised by a task comes back as that item's
:class:`Outcome`, so the caller reports it exactly as in one process. ``distributed`` is imported
only when a cluster is used: a run in this process starts as fast as before.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import os
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from importlib import metadata
from typing import Any, Generic, TypeVar

from app.cli import outputs
from paraloop_core.errors import ParaloopError

T = TypeVar("T")
R = TypeVar("R")

#: seconds allowed to reach a scheduler, and then for its first worker to be there
CONNECT_TIMEOUT = 10.0
#: the ``--workers`` default of the validations (many small tasks; solve runs in this process)
VALIDATE_WORKERS = min(2, os.cpu_count() or 1)
#: tasks in flight per worker thread: keeps every worker busy while bounding the memory of the
#: finished results that wait for an earlier, slower task (results are handed back in order)
IN_FLIGHT_PER_WORKER = 4


class ClusterError(ParaloopError):
    """The Dask cluster cannot be used: unreachable, no worker, another paraloop version."""

    reason = "cluster"


@dataclass(frozen=True)
class Outcome(Generic[R]):
    """The value of one task, or the exception it raised."""

    value: R | None = None
    error: Exception | None = None

    def get(self) -> R:
        """The value; re-raises the task's exception."""
        if self.error is not None:
            raise self.error
        return self.value  # type: ignore[return-value]


def _call(fn: Callable[..., R], *args: Any) -> Outcome[R]:
    try:
        return Outcome(fn(*args))
    except Exception as exc:  # the item's own failure; Ctrl-C (not an Exception) ends the run
        return Outcome(error=exc)


async def _identity(address: str) -> str:
    """The kind of Dask server at ``address`` (``Scheduler``, ``Worker``, ...)."""
    from distributed.comm import connect

    comm = await connect(address, timeout=CONNECT_TIMEOUT)
    try:
        await comm.write({"op": "identity", "reply": True})
        answer = await comm.read()
    finally:
        comm.abort()
    return str(answer.get("type")) if isinstance(answer, dict) else type(answer).__name__


class Bar:
    """Progress on stderr, ``[#####.....] 12/40 loops 3.1/s``; call it with the number done."""

    def __init__(self, total: int, unit: str) -> None:
        self.total, self.unit, self.start, self.shown = total, unit, time.perf_counter(), False

    def __call__(self, done: int) -> None:
        rate = done / max(time.perf_counter() - self.start, 1e-9)
        outputs.draw_bar(done / self.total, f"{done}/{self.total} {self.unit} {rate:.1f}/s")
        self.shown = done < self.total

    def clear(self) -> None:
        """Erase a drawn bar so that a message starts on a clean line (terminals only)."""
        if self.shown:
            sys.stderr.write("\r\x1b[K")
            sys.stderr.flush()
            self.shown = False


def add_arguments(p: argparse.ArgumentParser, default_workers: int = 1) -> None:
    """``--workers N`` or ``--dask ADDRESS`` (not both) for a command made of independent tasks."""
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", metavar="N", type=outputs.int_range(1, 256),
                       help="run on a local Dask cluster of N single-threaded worker processes; "
                            f"1: in this process (1..256, default {default_workers})")
    where.add_argument("--dask", metavar="ADDRESS",
                       help="run on the Dask cluster whose scheduler is at ADDRESS "
                            "(tcp://host:port); its workers need this paraloop version")
    p.set_defaults(default_workers=default_workers)


class Runner:
    """Where tasks run: in this process (``workers == 1``), on a local cluster of ``workers``
    single-threaded processes, or on the cluster at ``address`` (``workers`` becomes its thread
    count). A context manager: on exit, also by Ctrl-C, the client and a local cluster close."""

    def __init__(self, workers: int = 1, address: str | None = None) -> None:
        self.workers, self.address = workers, address
        self._client: Any = None
        self._cluster: Any = None

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> Runner:
        """The runner of ``--workers`` / ``--dask`` (:func:`add_arguments`)."""
        return cls(args.workers or args.default_workers, args.dask)

    def __enter__(self) -> Runner:
        try:
            if self.address is not None:
                self._connect(self.address)
            elif self.workers > 1:
                self._start_local()
        except BaseException:
            self.__exit__()
            raise
        return self

    def __exit__(self, *exc_info: object) -> None:
        outputs.seen(sys.exc_info()[1])  # a Ctrl-C unwinding: let the clean-up finish
        for part in (self._client, self._cluster):
            if part is not None:
                # a failure to shut down must not hide the run's own error (or Ctrl-C)
                with contextlib.suppress(Exception):
                    part.close()
        self._client = self._cluster = None

    def _start_local(self) -> None:
        import dask
        from distributed import Client, LocalCluster

        # Dask sets MALLOC_TRIM_THRESHOLD_ in its workers, which fixes glibc's mmap threshold:
        # our many mid-sized numpy arrays then cost ~20 % more time in mmap/munmap (measured)
        key = "distributed.nanny.pre-spawn-environ"
        environ = {**dask.config.get(key), "MALLOC_TRIM_THRESHOLD_": None}  # None: unset
        # the HTTP server on a free local port (no collision with another cluster); no logs
        # below critical: a failed task is reported for its item, stderr stays as in one process
        with dask.config.set({key: environ}):
            self._cluster = LocalCluster(n_workers=self.workers, threads_per_worker=1,
                                         processes=True, dashboard_address="127.0.0.1:0",
                                         silence_logs=logging.CRITICAL)
        self._client = Client(self._cluster, set_as_default=False)

    def _connect(self, address: str) -> None:
        from distributed import Client

        try:
            # a bounded handshake first: Client's own timeout does not cover a peer that
            # accepts the connection but never answers (e.g. the dashboard's HTTP port)
            kind = asyncio.run(asyncio.wait_for(_identity(address), CONNECT_TIMEOUT))
            if kind != "Scheduler":
                raise ValueError(f"the server there is a {kind}, not a Dask scheduler")
            self._client = Client(address, timeout=CONNECT_TIMEOUT, set_as_default=False)
        except (TimeoutError, asyncio.TimeoutError):
            raise ClusterError(f"--dask {address}: cannot connect (no answer within "
                               f"{CONNECT_TIMEOUT:g} s)") from None
        except Exception as exc:
            raise ClusterError(f"--dask {address}: cannot connect "
                               f"({type(exc).__name__}: {outputs.one_line(exc, 200)})") from None
        try:
            self._client.wait_for_workers(1, timeout=CONNECT_TIMEOUT)
        except (TimeoutError, asyncio.TimeoutError):
            raise ClusterError(f"--dask {address}: no worker joined the scheduler within "
                               f"{CONNECT_TIMEOUT:g} s (start some: dask worker {address})"
                               ) from None
        self.workers = sum(self._client.nthreads().values())
        mine = metadata.version("paraloop")
        theirs = self._client.run(metadata.version, "paraloop", on_error="return")
        for worker, version in sorted(theirs.items()):
            if version != mine:
                has = f"paraloop {version}" if isinstance(version, str) else "no paraloop"
                raise ClusterError(f"--dask {address}: worker {worker} has {has}, this machine "
                                   f"paraloop {mine}; install the same version on every worker")

    def outcomes(self, fn: Callable[[T], R], items: Iterable[T | Outcome[R]],
                 progress: Callable[[int], None] | None = None) -> Iterator[Outcome[R]]:
        """``fn(item)`` of each item, in input order; an Outcome among the items (an input that
        failed in this process, e.g. an unreadable file) takes its place without a task.
        ``progress(done)`` is called as tasks finish."""
        report = progress or (lambda done: None)
        if self._client is None:
            for done, item in enumerate(items, 1):
                outcome = item if isinstance(item, Outcome) else _call(fn, item)
                report(done)
                yield outcome
        else:
            yield from self._on_cluster(fn, items, report)

    def values(self, fn: Callable[[T], R], items: Iterable[T],
               progress: Callable[[int], None] | None = None) -> Iterator[R]:
        """The values of :meth:`outcomes`; the first error, in input order, is raised."""
        for outcome in self.outcomes(fn, items, progress):
            yield outcome.get()

    def _on_cluster(self, fn: Callable[[T], R], items: Iterable[T | Outcome[R]],
                    report: Callable[[int], None]) -> Iterator[Outcome[R]]:
        from distributed import as_completed

        source = enumerate(items)  # read lazily: at most `limit` inputs and results held
        limit = IN_FLIGHT_PER_WORKER * max(self.workers, 1)
        running: dict[Any, int] = {}  # future -> input index
        finished: dict[int, Outcome[R]] = {}  # waiting for an earlier item
        completed = as_completed(loop=self._client.loop)
        following = done = 0  # the next index to hand back; tasks finished
        more = True
        try:
            while True:
                while more and len(running) + len(finished) < limit:
                    entry = next(source, None)
                    if entry is None:
                        more = False
                    elif isinstance(entry[1], Outcome):
                        finished[entry[0]] = entry[1]
                        done += 1
                        report(done)
                    else:
                        # pure=False: equal inputs are still separate tasks with their own keys
                        future = self._client.submit(fn, entry[1], pure=False)
                        running[future] = entry[0]
                        completed.add(future)
                while following in finished:
                    yield finished.pop(following)
                    following += 1
                if not running:
                    if not more:
                        return
                    continue
                future = next(completed)
                finished[running.pop(future)] = _call(future.result)
                done += 1
                report(done)
        finally:  # the caller stopped early (an error, Ctrl-C): drop the work left, unless
            # the runner has closed already (closing the client released all of it)
            if running and self._client is not None:
                self._client.cancel(list(running))
