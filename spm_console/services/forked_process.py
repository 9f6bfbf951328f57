"""A process forked by the warm start (:mod:`.zygote`), seen from the front end that asked
for it: waited for and signalled through its pidfd, as :class:`subprocess.Popen` would be."""

from __future__ import annotations

import contextlib
import os
import select
import signal
import subprocess
import threading
from typing import Protocol

from spm_console.system.childproc import ProcessHandle


class MotionProcessHandle(ProcessHandle, Protocol):
    """What the motion client needs of its motion process (as :class:`subprocess.Popen`)."""

    def terminate(self) -> None: ...


#: The exit code reported for a fork whose end the warm start never reported (it died).
UNKNOWN_EXIT = 255


def readable(fd: int, timeout_s: float | None) -> bool:
    """Whether ``fd`` is readable within ``timeout_s`` (None: no limit)."""
    poller = select.poll()  # not select(): any fd number
    poller.register(fd, select.POLLIN)
    return bool(poller.poll(None if timeout_s is None else max(0, int(timeout_s * 1000))))


class ExitReports(Protocol):
    """The warm start's side: the exit codes of its forks, as it reports them."""

    def exit_code(self, pid: int, timeout_s: float) -> int | None: ...


class ForkedProcess:
    """A process forked by the warm start (a motion process, or a helper such as the emulated
    bus): waited for and signalled through its pidfd (this process is not its parent); its
    exit code as the warm start reports it. Thread-safe (the motion client polls it from
    several threads)."""

    def __init__(self, pid: int, pidfd: int, starter: ExitReports) -> None:
        self._pid = pid
        self._pidfd = pidfd
        self._starter = starter
        self._lock = threading.Lock()
        self.returncode: int | None = None

    @property
    def pid(self) -> int:
        return self._pid

    def _settle(self, timeout_s: float | None) -> int | None:
        """The exit code once the process has ended within ``timeout_s``, else None."""
        with self._lock:
            if self.returncode is not None:
                return self.returncode
            fd = self._pidfd
        if fd >= 0 and not readable(fd, timeout_s):
            return None
        code = self._starter.exit_code(self._pid, 0.0 if timeout_s == 0 else 2.0)
        with self._lock:
            if self.returncode is None:
                if code is None and timeout_s == 0:
                    return None  # ended; its code is on its way
                self.returncode = UNKNOWN_EXIT if code is None else code
                if self._pidfd >= 0:
                    os.close(self._pidfd)
                    self._pidfd = -1
            return self.returncode

    def poll(self) -> int | None:
        return self._settle(0)

    def wait(self, timeout: float | None = None) -> int:
        code = self._settle(timeout)
        if code is None:
            raise subprocess.TimeoutExpired("a fork of the warm start", timeout or 0.0)
        return code

    def send_signal(self, sig: int) -> None:
        with self._lock:
            if self.returncode is None and self._pidfd >= 0:
                with contextlib.suppress(ProcessLookupError):
                    signal.pidfd_send_signal(self._pidfd, sig)

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)
