"""A command in a terminal of its own, as an operator's shell runs it.

:class:`Terminal` starts a command as the session leader of a new session whose
controlling terminal is a fresh pseudo-terminal: typing Ctrl-C or Ctrl-\\ on it makes
the kernel signal the foreground process group, closing it (the master side) hangs it
up (SIGHUP to the session), and :meth:`Terminal.signal_group` is ``kill -- -PGID``.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import select
import signal
import subprocess
import termios
import threading
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from spm_console.errors import ExitCode
from spm_console.motion.logs.runlog import list_runs, load_run

CTRL_C = b"\x03"
CTRL_BACKSLASH = b"\x1c"


def _take_terminal() -> None:  # in the child, after setsid and the dup2 of stdio
    fcntl.ioctl(0, termios.TIOCSCTTY, 0)


class Terminal:
    """``args`` in a new session on a new pty; its output is kept (:attr:`output`)."""

    def __init__(self, args: Sequence[str], env: dict[str, str], cwd: Path | None = None) -> None:
        master, slave = os.openpty()
        self.master: int | None = master
        self.proc = subprocess.Popen(list(args), stdin=slave, stdout=slave, stderr=slave,
                                     env=env, cwd=cwd, start_new_session=True,
                                     preexec_fn=_take_terminal)
        os.close(slave)
        self._out = bytearray()
        self._closing = threading.Event()
        self._reader = threading.Thread(target=self._read, args=(master,), daemon=True)
        self._reader.start()

    def _read(self, fd: int) -> None:
        """Keep what the command prints. Never blocked in a read: :meth:`close` must release
        the master at once (a read in flight would hold the terminal open)."""
        while not self._closing.is_set():
            if not select.select([fd], [], [], 0.02)[0]:
                continue
            try:
                data = os.read(fd, 4096)
            except OSError:  # EIO once every slave is closed
                return
            if not data:
                return
            self._out += data

    @property
    def output(self) -> str:
        return self._out.decode("utf-8", "replace")

    def type(self, data: bytes) -> None:
        """Type on the terminal (Ctrl-C and Ctrl-\\ become signals to the foreground group)."""
        assert self.master is not None
        os.write(self.master, data)

    def signal_group(self, sig: signal.Signals) -> None:
        """``kill -SIG -- -PGID``: every process of the command's process group."""
        os.killpg(self.proc.pid, sig)

    def close(self) -> None:
        """The terminal window closes (the pty master goes away: hang-up)."""
        if self.master is not None:
            fd, self.master = self.master, None
            self._closing.set()
            self._reader.join(1.0)
            os.close(fd)

    def wait(self, timeout_s: float = 30.0) -> int:
        code = self.proc.wait(timeout_s)
        if self.master is not None:
            self._reader.join(1.0)
        return code

    def kill(self) -> None:
        """Clean-up: nothing of the command survives the test."""
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait(10)
        self.close()


def wait_until(predicate: object, what: str, timeout_s: float = 30.0,
               proc: subprocess.Popen[bytes] | None = None) -> None:
    """Poll ``predicate()`` every 20 ms; fail (never hang) after ``timeout_s``."""
    assert callable(predicate)
    t_end = time.monotonic() + timeout_s
    while not predicate():
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"{what}: the process ended first (exit {proc.returncode})")
        if time.monotonic() > t_end:
            raise AssertionError(f"{what}: not after {timeout_s} s")
        time.sleep(0.02)


#: The repeated hold's own transaction, s: a sync write of three goals is 29 bytes, 0.29 ms on
#: the wire at the profile's 1 Mbaud (10 bits a byte); done_t is stamped after it.
HOLD_WRITE_S = 1e-3


def assert_estopped(logs: Path, run_dir: Path, sig: signal.Signals, ts_s: float,
                    loop_pid: int, *, where: str = "") -> None:
    """The motion ended in the E-stop with the hold written within two periods of the
    request (the repeat's own bytes on the wire aside); every log is closed; the motion
    process is gone."""
    run = load_run(run_dir)
    assert run.meta["outcome"] == "stopped" and run.meta["exit_code"] == int(ExitCode.STOP_ESTOP)
    assert run.meta["message"] == f"E-stop: signal {sig.name}{where}", run.meta["message"]
    assert not run.truncated
    stop = next(e for e in run.events if e["event"] == "stop")
    assert stop["kind"] == "estop" and stop["action"] == "hold" and stop["notes"] == []
    assert stop["requested_t"] is not None
    # the hold is written when the loop meets the request, within a period (a request that
    # lands while the loop waits for its deadline is stamped with the wait's start: a whole
    # period before), and again at the next deadline, done after its own bytes on the wire
    assert stop["done_t"] - stop["requested_t"] <= 2 * ts_s + HOLD_WRITE_S, stop
    np.testing.assert_allclose(stop["hold_deg"], last_measured(run.vec("meas")), atol=1e-3)
    assert all(r.meta["outcome"] != "running" for r in list_runs(logs))
    wait_until(lambda: not alive(loop_pid), "the motion process ends", 10.0)


def alive(pid: int) -> bool:
    try:
        return not Path(f"/proc/{pid}/stat").read_text().rsplit(") ", 1)[1].startswith("Z")
    except OSError:
        return False


def last_measured(meas: np.ndarray) -> np.ndarray:
    """The last finite measured row: the hold is the last good reading (a cycle whose reply
    was lost logs NaN and holds the one before)."""
    ok = np.flatnonzero(np.isfinite(meas).all(axis=1))
    assert ok.size, "no reading in the run"
    return np.asarray(meas[ok[-1]])
