"""A row map (:class:`~spm_console.core.workspace.rowmap.RowMap`) that splits the rows with one forked
child process: the child computes the first half while this process computes the second.

The child is forked when a function is first given (it inherits that function and all it
refers to: no workspace is copied or pickled) and serves it until another function comes or
the map is closed; only the rows and the results cross the pipe. It forks only where that is
safe and useful: on a platform with ``fork``, from a process running one thread (a fork never
copies a thread holding a lock the child would need: the console, which runs threads, builds
in one process), not under a real-time policy, and with at least two CPUs to run on;
otherwise, and for small inputs, the map runs ``fn`` in this process. Anything that goes
wrong in the child (an exception, its death) makes this process compute the child's half
itself, so the result, or the exception, is the one ``fn(*rows)`` gives. Used by workspace
builds (``models.build_workspace``).
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from collections.abc import Callable
from multiprocessing import Pipe
from multiprocessing.connection import Connection
from types import TracebackType
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

R = TypeVar("R")

#: Fewer rows than this run in this process (the pipe's round trip would cost more).
MIN_ROWS = 200
#: Seconds to wait for the child to exit when the map is closed, before killing it.
EXIT_WAIT_S = 2.0


def _realtime() -> bool:
    """True when this thread runs under a real-time policy (SCHED_FIFO or SCHED_RR)."""
    try:
        return os.sched_getscheduler(0) in (os.SCHED_FIFO, os.SCHED_RR)
    except (AttributeError, OSError):
        return False


def fork_useful() -> bool:
    """True when forking a helper is safe and can help: ``fork`` exists, this process runs one
    thread, not at a real-time priority (the servo loop's process never forks: it runs threads
    and its helper would inherit SCHED_FIFO), and it may run on at least two CPUs."""
    if not hasattr(os, "fork") or threading.active_count() != 1 or _realtime():
        return False
    try:
        cpus = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cpus = os.cpu_count() or 1
    return cpus >= 2


class _Failed:
    """The child's answer when ``fn`` raised: this process computes that half again."""

    def __init__(self, what: str) -> None:
        self.what = what


def _serve(conn: Connection, fn: Callable[..., Any]) -> None:
    """The child: answer each batch of rows with ``fn(*rows)`` until None or the pipe closes."""
    while True:
        try:
            rows = conn.recv()
        except (EOFError, OSError):
            return
        if rows is None:
            return
        try:
            out: Any = fn(*rows)
        except Exception as exc:  # the parent computes this half and meets the error itself
            out = _Failed(repr(exc))
        conn.send(out)


def _join(first: Any, second: Any) -> Any:
    """Rows of ``first`` then of ``second`` (arrays, or tuples of arrays)."""
    if isinstance(first, tuple):
        return tuple(np.concatenate([a, b]) for a, b in zip(first, second, strict=True))
    return np.concatenate([first, second])


class ForkedRows:
    """Row map with one forked helper (module docstring). Use as a context manager: closing
    stops and reaps the child."""

    def __init__(self, min_rows: int = MIN_ROWS) -> None:
        self.min_rows = int(min_rows)
        self.enabled = fork_useful()
        self.forks = 0
        """Children forked so far."""
        self.split_calls = 0
        """Calls whose rows were split with the child."""
        self._fn: Callable[..., Any] | None = None
        self._pid = 0
        self._conn: Connection | None = None

    @property
    def child_pid(self) -> int:
        """The helper's process id, 0 when none runs."""
        return self._pid

    def __enter__(self) -> ForkedRows:
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def __call__(self, fn: Callable[..., R], *rows: NDArray[Any]) -> R:
        n = len(rows[0]) if rows else 0
        if not self.enabled or n < self.min_rows:
            return fn(*rows)
        if self._fn is not fn:
            self._start(fn)
        conn = self._conn
        if conn is None:  # no helper after all (a thread started since)
            return fn(*rows)
        m = n // 2
        first = tuple(r[:m] for r in rows)
        try:
            conn.send(first)
        except (OSError, ValueError):
            self._lost()
            return fn(*rows)
        try:
            second = fn(*(r[m:] for r in rows))
        except BaseException:  # the child's answer would be read by the next call: stop it
            self._stop()
            raise
        try:
            got: Any = conn.recv()
        except (EOFError, OSError):
            self._lost()
            got = _Failed("the helper process ended")
        if isinstance(got, _Failed):
            got = fn(*first)
        self.split_calls += 1
        joined: R = _join(got, second)
        return joined

    def _start(self, fn: Callable[..., Any]) -> None:
        self._stop()
        if not fork_useful():  # a thread started since: stay in this process
            self.enabled = False
            return
        ours, theirs = Pipe()
        pid = os.fork()
        if pid == 0:  # the child: serve, then leave without running the parent's exit code
            code = 0
            try:
                for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
                    signal.signal(sig, signal.SIG_DFL)  # not the parent's handlers
                ours.close()
                _serve(theirs, fn)
            except BaseException:  # a broken pipe when the parent is gone
                code = 1
            finally:
                os._exit(code)
        theirs.close()
        self._pid, self._conn, self._fn = pid, ours, fn
        self.forks += 1

    def _lost(self) -> None:
        """The child is gone: reap it and compute everything here from now on."""
        self.close()

    def close(self) -> None:
        """Stop the child (if any) and wait for it (kill it after :data:`EXIT_WAIT_S`); from
        now on every call runs in this process."""
        self.enabled = False
        self._stop()

    def _stop(self) -> None:
        conn, pid = self._conn, self._pid
        self._conn, self._pid, self._fn = None, 0, None
        if conn is not None:
            with contextlib.suppress(OSError, ValueError):
                conn.send(None)
            conn.close()
        if pid:
            _reap(pid)


def _reap(pid: int) -> None:
    deadline = time.monotonic() + EXIT_WAIT_S
    while True:
        try:
            done, _ = os.waitpid(pid, os.WNOHANG)
        except ChildProcessError:
            return
        if done:
            return
        if time.monotonic() > deadline:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, 9)
            with contextlib.suppress(ChildProcessError):
                os.waitpid(pid, 0)
            return
        time.sleep(0.002)
