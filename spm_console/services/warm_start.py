"""Starting the motion process: forked from a warm start (:mod:`.zygote`), or directly.

:func:`start_motion_process` hands the motion process its end of the socket pair and
returns a :class:`MotionProcessHandle` (poll, wait, signal), whichever way it was started:

* **warm** (the default): the first call starts one warm-start process for this front end
  (it imports what a motion process needs, about 2 s, once); each motion process is then
  forked from it in milliseconds, with this process's environment and working directory of
  the moment. If the warm start cannot be used (it failed to start, or died), the motion
  process is started directly instead;
* **direct** (``SPM_CONSOLE_WARM_START=0``): ``python -m spm_console.motion.server`` is
  started for each motion process, in a session of its own.

Either way the motion process runs in a session of its own: a signal to the front end's
process group or terminal never reaches the servo loop (:mod:`spm_console.motion.server`).
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import socket
import subprocess
import sys
import threading
from collections.abc import Callable
from typing import Protocol

#: Environment variable: ``0`` starts every motion process directly.
ENV_WARM_START = "SPM_CONSOLE_WARM_START"
#: Seconds to wait for the warm start to be ready (it imports numpy, scipy, the solvers).
READY_TIMEOUT_S = 60.0
#: Seconds to wait for a fork's pid once the warm start is ready.
FORK_TIMEOUT_S = 10.0
#: Largest message read from the warm start, bytes.
MAX_MESSAGE = 4096


class MotionProcessHandle(Protocol):
    """What the motion client needs of its motion process (as :class:`subprocess.Popen`)."""

    @property
    def pid(self) -> int: ...

    def poll(self) -> int | None: ...

    def wait(self, timeout: float | None = None) -> int: ...

    def send_signal(self, sig: int) -> None: ...

    def terminate(self) -> None: ...


class ForkedProcess:
    """A motion process forked by the warm start: waited for and signalled through its
    pidfd (this process is not its parent); its exit code as the warm start reports it."""

    def __init__(self, pid: int, pidfd: int, starter: WarmStart) -> None:
        self._pid = pid
        self._pidfd = pidfd
        self._starter = starter
        self.returncode: int | None = None

    @property
    def pid(self) -> int:
        return self._pid

    def _ended(self, timeout: float | None) -> bool:
        if self._pidfd < 0:
            return True
        ready, _, _ = select.select([self._pidfd], [], [], timeout)
        return bool(ready)

    def poll(self) -> int | None:
        if self.returncode is None and self._ended(0.0):
            self.returncode = self._starter.exit_code(self._pid)
            self._close()
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        if self.returncode is None:
            if not self._ended(timeout):
                raise subprocess.TimeoutExpired("motion process", timeout or 0.0)
            self.returncode = self._starter.exit_code(self._pid)
            self._close()
        return self.returncode

    def send_signal(self, sig: int) -> None:
        if self.returncode is None and self._pidfd >= 0:
            with contextlib.suppress(ProcessLookupError):
                signal.pidfd_send_signal(self._pidfd, sig)

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def _close(self) -> None:
        if self._pidfd >= 0:
            os.close(self._pidfd)
            self._pidfd = -1


class WarmStart:
    """This front end's warm-start process (one per process; started on first use)."""

    def __init__(self) -> None:
        mine, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        self.process = subprocess.Popen(
            [sys.executable, "-m", "spm_console.services.zygote", "--fd", str(theirs.fileno())],
            pass_fds=(theirs.fileno(),), stdin=subprocess.DEVNULL,
            # stdout belongs to the front end (a --json answer); a motion process has nothing
            # to say there (a bug's traceback goes to stderr)
            stdout=subprocess.DEVNULL, start_new_session=True)
        theirs.close()
        self._sock = mine
        self._owner = os.getpid()
        self._lock = threading.Lock()
        self._cond = threading.Condition()
        self._exits: dict[int, int] = {}
        self._forks: list[tuple[int, int]] = []
        self._gone = False
        self._ready = False
        if not self._wait_for(lambda: self._ready, READY_TIMEOUT_S, first=True):
            self.close()
            raise OSError("the warm start of the motion process did not become ready")
        threading.Thread(target=self._read, daemon=True, name="spm-warm-start").start()

    def _handle(self, data: bytes, fds: list[int]) -> None:
        msg = json.loads(data)
        with self._cond:
            if "ready" in msg:
                self._ready = True
            elif "pid" in msg and len(fds) == 1:
                self._forks.append((int(msg["pid"]), fds[0]))
                fds = []
            elif "exit" in msg:
                self._exits[int(msg["exit"])] = int(msg["code"])
            self._cond.notify_all()
        for f in fds:
            os.close(f)

    def _recv_one(self) -> bool:
        try:
            data, fds, _, _ = socket.recv_fds(self._sock, MAX_MESSAGE, 1)
        except OSError:
            data, fds = b"", []
        if not data:
            with self._cond:
                self._gone = True
                self._cond.notify_all()
            return False
        self._handle(data, fds)
        return True

    def _read(self) -> None:
        while self._recv_one():
            pass

    def _wait_for(self, done: Callable[[], bool], timeout_s: float, first: bool = False) -> bool:
        """Until ``done()`` (under the condition); ``first``: read the socket here (the
        reader thread is not running yet)."""
        if first:
            while not done():
                ready, _, _ = select.select([self._sock], [], [], timeout_s)
                if not ready or not self._recv_one():
                    return False
            return True
        with self._cond:
            return bool(self._cond.wait_for(lambda: done() or self._gone, timeout_s)) and done()

    @property
    def alive(self) -> bool:
        return not self._gone and os.getpid() == self._owner and self.process.poll() is None

    def fork(self, theirs: socket.socket) -> ForkedProcess:
        """A motion process serving ``theirs`` (raises OSError if the warm start is gone)."""
        req = json.dumps({"env": dict(os.environ), "cwd": os.getcwd()}).encode()
        with self._lock:
            socket.send_fds(self._sock, [req], [theirs.fileno()])
            if not self._wait_for(lambda: bool(self._forks), FORK_TIMEOUT_S):
                raise OSError("the warm start of the motion process did not fork")
            with self._cond:
                pid, pidfd = self._forks.pop(0)
        return ForkedProcess(pid, pidfd, self)

    def exit_code(self, pid: int) -> int:
        """The exit code of a fork that has ended (-1 if the warm start never reported it)."""
        self._wait_for(lambda: pid in self._exits, 2.0)
        with self._cond:
            return self._exits.pop(pid, -1)

    def close(self) -> None:
        with contextlib.suppress(OSError):  # the reader thread's recv returns; the peer sees EOF
            self._sock.shutdown(socket.SHUT_RDWR)
        with contextlib.suppress(OSError):
            self._sock.close()
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.process.wait(2.0)


_starter: WarmStart | None = None
_starter_lock = threading.Lock()


def _warm_start() -> WarmStart | None:
    """This process's warm start (started on first use), or None when it is not to be used
    or cannot be."""
    global _starter
    if os.environ.get(ENV_WARM_START, "1").strip().lower() in ("0", "no", "off", "false"):
        return None
    with _starter_lock:
        if _starter is None or not _starter.alive:
            try:
                _starter = WarmStart()
            except OSError:
                _starter = None
        return _starter


def start_direct(theirs: socket.socket) -> subprocess.Popen[bytes]:
    """``python -m spm_console.motion.server`` on ``theirs``, in a session of its own."""
    return subprocess.Popen(
        [sys.executable, "-m", "spm_console.motion.server", "--fd", str(theirs.fileno())],
        pass_fds=(theirs.fileno(),), stdin=subprocess.DEVNULL,
        # its own session: a signal to the front end's process group (Ctrl-C, Ctrl-\, the
        # terminal closing, ``kill -- -PGID``, ``timeout``) reaches the front end, which
        # E-stops through this connection; the servo loop is never killed by it
        start_new_session=True)


def start_motion_process(theirs: socket.socket) -> MotionProcessHandle:
    """The motion process serving ``theirs`` (see the module docstring)."""
    starter = _warm_start()
    if starter is not None:
        try:
            return starter.fork(theirs)
        except OSError:
            pass  # the warm start is gone: start this one directly
    return start_direct(theirs)
