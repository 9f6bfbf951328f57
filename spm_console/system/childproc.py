"""Helper child processes (the 3D viewer's server, the emulated bus for the console):
started as children, stopped on exit and on SIGTERM.

:class:`ChildProcess` runs ``python -m MODULE --parent PID …``; the child prints one
JSON line on stdout when it is ready and watches its parent, so it never outlives a
killed console. A helper the caller can have forked elsewhere (its ``fork``: the front end's
warm start, whose imports are done) is started that way first, on pipes of this process.
"""

from __future__ import annotations

import atexit
import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Sequence
from typing import IO, Any, Protocol

from spm_console.errors import SpmError

#: Seconds to wait for a child to report that it is ready.
START_TIMEOUT_S = 15.0

_spares: dict[str, subprocess.Popen[bytes]] = {}
"""Children started ahead by :func:`prespawn`, by module, waiting for their request."""
_spare_env: dict[str, dict[str, str]] = {}
"""The environment each spare started with (it reads its settings from it)."""
_spares_lock = threading.Lock()


def _spawn(module: str, args: Sequence[str]) -> subprocess.Popen[bytes]:
    cmd = [sys.executable, "-u", "-m", module, "--parent", str(os.getpid()), *args]
    return subprocess.Popen(
        cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
        start_new_session=True,  # Ctrl-C in the terminal does not reach it; we stop it
    )


def _kill_spares() -> None:
    with _spares_lock:
        spares = list(_spares.values())
        _spares.clear()
        _spare_env.clear()
    for proc in spares:
        _discard(proc)


def _discard(proc: subprocess.Popen[bytes]) -> None:
    """End a spare that was never used (it reads EOF as its request, then leaves; killed if
    it lingers)."""
    for stream in (proc.stdin, proc.stdout):
        if stream is not None:
            with contextlib.suppress(OSError):
                stream.close()
    try:
        proc.wait(2.0)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(2.0)


def prespawn(module: str) -> None:
    """Start the child ``python -m module`` (no extra arguments) now, so that its imports
    overlap this process's own; the next :meth:`ChildProcess.start` of that module takes it.
    One spare per module; an unused spare is ended when this process exits. A spare is taken
    only while this process's environment is the one it started with (the child reads its
    settings there: real-time scheduling, the clock); else it is ended and a child started."""
    with _spares_lock:
        if module in _spares:
            return
        try:
            _spares[module] = _spawn(module, ())
        except OSError:
            return  # started when it is needed, as without a spare
        _spare_env[module] = dict(os.environ)
    atexit.register(_kill_spares)


def _take_spare(module: str, args: Sequence[str]) -> subprocess.Popen[bytes] | None:
    if args:
        return None
    with _spares_lock:
        proc = _spares.pop(module, None)
        env = _spare_env.pop(module, None)
    if proc is not None and (proc.poll() is not None or env != dict(os.environ)):
        _discard(proc)
        return None
    return proc


class ProcessHandle(Protocol):
    """A started process, as :class:`subprocess.Popen` gives it."""

    @property
    def pid(self) -> int: ...

    def poll(self) -> int | None: ...

    def wait(self, timeout: float | None = None) -> int: ...

    def send_signal(self, sig: int) -> None: ...

    def kill(self) -> None: ...


class HelperProcess(ProcessHandle, Protocol):
    """A helper's process with its standard input and output, as :class:`subprocess.Popen`
    (``stdin=PIPE, stdout=PIPE``) gives it."""

    @property
    def stdin(self) -> IO[bytes] | None: ...

    @property
    def stdout(self) -> IO[bytes] | None: ...


#: Forks the helper ``module`` on the ends (standard input's read end, standard output's
#: write end) of two pipes; None when it cannot (the helper is then started as a process).
HelperFork = Callable[[str, int, int], ProcessHandle | None]


class PipedProcess:
    """A process started elsewhere (forked by a warm start) on pipes of this process."""

    def __init__(self, proc: ProcessHandle, stdin: IO[bytes], stdout: IO[bytes]) -> None:
        self._proc = proc
        self.stdin: IO[bytes] | None = stdin
        self.stdout: IO[bytes] | None = stdout

    @property
    def pid(self) -> int:
        return self._proc.pid

    def poll(self) -> int | None:
        return self._proc.poll()

    def wait(self, timeout: float | None = None) -> int:
        return self._proc.wait(timeout)

    def send_signal(self, sig: int) -> None:
        self._proc.send_signal(sig)

    def kill(self) -> None:
        self._proc.kill()


def _forked(fork: HelperFork, module: str) -> HelperProcess | None:
    """``module`` forked by ``fork`` on two new pipes (their other ends here), or None."""
    in_r, in_w = os.pipe()
    out_r, out_w = os.pipe()
    try:
        proc = fork(module, in_r, out_w)
    except OSError:  # asked, no answer: a fork, if any, reads EOF as its request and leaves
        proc = None
    finally:  # the fork has its own copies
        os.close(in_r)
        os.close(out_w)
    if proc is None:
        os.close(in_w)
        os.close(out_r)
        return None
    return PipedProcess(proc, os.fdopen(in_w, "wb", buffering=0), os.fdopen(out_r, "rb"))


class HelperProcessError(SpmError):
    """A helper process (3D viewer, emulator child) failed or does not answer."""


class ChildProcess:
    """One helper child process announcing itself with a JSON line."""

    stop_signal: signal.Signals = signal.SIGTERM
    """What :meth:`stop` sends first (then SIGKILL if the child lingers)."""

    def __init__(self, module: str, args: Sequence[str] = (), what: str = "helper",
                 fork: HelperFork | None = None) -> None:
        self.module = module
        self.args = list(args)
        self.what = what
        self.fork = fork
        """Forks the helper instead of starting a process (no extra ``args`` only)."""
        self.forked = False
        """The helper was forked by :attr:`fork` (not started as a process of its own)."""
        self._proc: HelperProcess | None = None
        self.info: dict[str, Any] | None = None

    @property
    def pid(self) -> int | None:
        return self._proc.pid if self._proc is not None else None

    @property
    def running(self) -> bool:
        return self._proc is not None and self._proc.poll() is None

    def start(self, stdin: bytes = b"", timeout_s: float = START_TIMEOUT_S) -> dict[str, Any]:
        """Spawn the child (or take the one :func:`prespawn` started, or have it forked), send
        ``stdin``, wait for its JSON line (blocking)."""
        proc: HelperProcess | None = _take_spare(self.module, self.args)
        if proc is None and self.fork is not None and not self.args:
            proc = _forked(self.fork, self.module)
            self.forked = proc is not None
        self._proc = proc or _spawn(self.module, self.args)
        atexit.register(self.stop)
        assert self._proc.stdin is not None
        try:
            self._proc.stdin.write(stdin)
            self._proc.stdin.close()
        except OSError:
            pass  # it died at once: reported below
        line = self._read_line(timeout_s)
        try:
            data = json.loads(line)
            if not isinstance(data, dict):
                raise ValueError(line)
        except ValueError:
            self.stop()
            raise HelperProcessError(f"{self.what} did not start (said {line[:300]!r})") from None
        if "error" in data:
            self.stop()
            raise HelperProcessError(f"{self.what}: {data['error']}")
        self.info = data
        return data

    def _read_line(self, timeout_s: float) -> str:
        proc = self._proc
        assert proc is not None and proc.stdout is not None
        stdout = proc.stdout
        out: list[bytes] = []
        reader = threading.Thread(target=lambda: out.append(stdout.readline()), daemon=True)
        reader.start()
        reader.join(timeout_s)
        if not out:
            self.stop()
            raise HelperProcessError(f"{self.what} did not start within {timeout_s:.0f} s")
        return out[0].decode("utf-8", "replace").strip()

    def stop(self, timeout_s: float = 2.0) -> None:
        """Terminate the child (then kill it if it lingers); safe to call twice."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        if proc.poll() is None:
            proc.send_signal(self.stop_signal)
            try:
                proc.wait(timeout_s)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout_s)
        if proc.stdout is not None:
            proc.stdout.close()
        atexit.unregister(self.stop)
