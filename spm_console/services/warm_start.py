"""Starting the motion process: forked from a warm start (:mod:`.zygote`), or directly.

:func:`start_motion_process` hands the motion process its end of the socket pair and
returns a :class:`MotionProcessHandle` (poll, wait, signal), whichever way it was started
(``SPM_CONSOLE_WARM_START``):

* **resident** (the default): the front end connects to this user's resident warm start
  for this installation (:mod:`spm_console.system.resident`), starting it when there is none. It outlives the
  command, so from the second command on the motion process is forked in milliseconds
  instead of importing for about 2 s. It retires by itself when idle, on SIGTERM
  (``spm-console warm-start --stop``), and when the code it imported changed on disk;
* **command**: the first call starts one warm-start process for this front end alone (its
  imports overlap the front end's own when :func:`prestart` started it); it ends with it;
* **direct** (``0``): ``python -m spm_console.motion.server`` is started for each motion
  process, in a session of its own.

When a warm start cannot be used (it failed to start, died, or refused the request) before
it was handed the socket, the motion process is started directly instead; once it has been
handed the socket, a failure is an error (never two processes on one socket).

Either way the motion process runs in a session of its own: a signal to the front end's
process group or terminal never reaches the servo loop (:mod:`spm_console.motion.server`).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import threading
from collections.abc import Callable

from spm_console.services.forked_process import ForkedProcess, MotionProcessHandle, readable
from spm_console.system import resident
from spm_console.system.env import switched_off

#: Environment variable: ``0`` starts every motion process directly, ``command`` from a warm
#: start of this front end's own; anything else from the resident warm start.
ENV_WARM_START = "SPM_CONSOLE_WARM_START"
#: The value of :data:`ENV_WARM_START` for a warm start per front end.
PER_COMMAND = "command"
#: Seconds to wait for the warm start to be ready (it imports numpy, scipy, the solvers).
READY_TIMEOUT_S = 60.0
#: Seconds to wait for a fork's pid once the warm start is ready.
FORK_TIMEOUT_S = 10.0
#: Largest message read from the warm start, bytes.
MAX_MESSAGE = 4096


def _umask() -> int:
    """This process's umask, read without changing it (``/proc``; Linux 4.7)."""
    with contextlib.suppress(OSError, ValueError), open("/proc/self/status") as f:
        for line in f:
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    mask = os.umask(0o022)  # no /proc: the one reading that sets it
    os.umask(mask)
    return mask


def _has_fd(stream: object) -> bool:
    """Whether ``stream`` is backed by an open file descriptor (a console's captured stderr
    says -1: the process's own fd 2 is handed over instead)."""
    try:
        fd = stream.fileno()  # type: ignore[attr-defined]
        if not isinstance(fd, int) or fd < 0:
            return False
        os.fstat(fd)
        return True
    except (AttributeError, OSError, ValueError):
        return False


class NotSentError(OSError):
    """The warm start could not be asked, or refused the request: the motion process's
    socket is still unused (a direct start may serve it)."""


class WarmStart:
    """A connection to a warm start: this front end's own (``process`` is it) or the
    resident one (``process`` is None)."""

    def __init__(self, sock: socket.socket, process: subprocess.Popen[bytes] | None) -> None:
        self.process = process
        self._sock = sock
        self._owner = os.getpid()
        self._lock = threading.Lock()
        self._cond = threading.Condition()
        self._exits: dict[int, int] = {}
        self._answers: dict[int, tuple[int, int] | str] = {}
        self._waiting: set[int] = set()
        self._next_id = 1
        self._gone = False
        self._ready = False
        self.pid = 0
        self.unsupported = ""
        self.stale = ""

    @classmethod
    def own(cls) -> WarmStart:
        """A warm start for this front end alone, started now."""
        mine, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        with theirs:
            process = subprocess.Popen(
                [sys.executable, "-m", "spm_console.services.zygote",
                 "--fd", str(theirs.fileno())],
                pass_fds=(theirs.fileno(),), stdin=subprocess.DEVNULL,
                # stdout belongs to the front end (a --json answer); a motion process has
                # nothing to say there (a bug's traceback goes to stderr)
                stdout=subprocess.DEVNULL, start_new_session=True)
        return cls(mine, process)

    @classmethod
    def resident(cls, path: str) -> WarmStart:
        """A connection to the resident warm start at ``path`` (started when there is none)."""
        return cls(resident.connect(path), None)

    def await_ready(self) -> None:
        """Wait until the warm start has imported what a motion process needs (NotSentError
        when it cannot be used), then read its messages from a thread of this process."""
        if not self._wait_for(lambda: self._ready or bool(self.unsupported or self.stale),
                              READY_TIMEOUT_S, first=True) or not self._ready:
            self.close()
            raise NotSentError(self.unsupported or self.stale
                               or "the warm start of the motion process did not become ready")
        threading.Thread(target=self._read, daemon=True, name="spm-warm-start").start()

    def _handle(self, data: bytes, fds: list[int]) -> None:
        msg = json.loads(data)
        late: list[int] = []
        with self._cond:
            if "ready" in msg:
                self._ready = True
                self.pid = int(msg["ready"])
            elif "stale" in msg:
                self.stale = f"the resident warm start retired: {msg['stale']}"
            elif "unsupported" in msg:
                self.unsupported = str(msg["unsupported"])
            elif "id" in msg:
                ident = int(msg["id"])
                if ident in self._waiting and "pid" in msg and len(fds) == 1:
                    self._answers[ident] = (int(msg["pid"]), fds.pop())
                elif ident in self._waiting:
                    self._answers[ident] = str(msg.get("error", "no pidfd"))
                else:
                    late = fds  # an answer nobody waits for any more: stop that fork
                    fds = []
            elif "exit" in msg:
                self._exits[int(msg["exit"])] = int(msg["code"])
            self._cond.notify_all()
        for f in late:
            with contextlib.suppress(OSError):
                signal.pidfd_send_signal(f, signal.SIGKILL)
            os.close(f)
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
                if not readable(self._sock.fileno(), timeout_s) or not self._recv_one():
                    return False
            return True
        with self._cond:
            return bool(self._cond.wait_for(lambda: done() or self._gone, timeout_s)) and done()

    @property
    def alive(self) -> bool:
        return not self._gone and os.getpid() == self._owner and (
            self.process is None or self.process.poll() is None)

    def fork(self, theirs: socket.socket) -> ForkedProcess:
        """A motion process serving ``theirs``. :class:`NotSentError` when the warm start
        could not be asked, or refused before any fork of it touched ``theirs`` (a front end
        niced below it, a bad request): another process may serve it; OSError when it was
        asked and gave no answer (``theirs`` may have been handed over: it must not be served
        by another process)."""
        err = sys.stderr.fileno() if _has_fd(sys.stderr) else 2
        return self._ask([theirs.fileno(), err], {})

    def fork_helper(self, module: str, stdin_fd: int, stdout_fd: int) -> ForkedProcess:
        """The helper ``module`` (one the warm start knows, see :mod:`.zygote_forks`) with
        these ends of its standard input and output, watching this process as its parent;
        errors as :meth:`fork`'s."""
        return self._ask([stdin_fd, stdout_fd], {"helper": module, "parent": os.getpid()})

    def _ask(self, fds: list[int], extra: dict[str, object]) -> ForkedProcess:
        with self._cond:
            ident = self._next_id
            self._next_id += 1
            self._waiting.add(ident)
        req = json.dumps({"id": ident, "env": dict(os.environ), "cwd": os.getcwd(),
                          "umask": _umask(), "cpus": sorted(os.sched_getaffinity(0)),
                          "nice": os.getpriority(os.PRIO_PROCESS, 0), **extra}).encode()
        try:
            with self._lock:
                try:
                    socket.send_fds(self._sock, [req], fds)
                except OSError as exc:
                    raise NotSentError(str(exc)) from None
            got = self._wait_for(lambda: ident in self._answers, FORK_TIMEOUT_S)
        finally:
            with self._cond:
                self._waiting.discard(ident)
                answer = self._answers.pop(ident, None)
        if not got or answer is None:
            raise OSError("the warm start did not fork in time")
        if isinstance(answer, str):  # it says so only when no fork of it touched the fds
            raise NotSentError(f"the warm start refused: {answer}")
        return ForkedProcess(answer[0], answer[1], self)

    def exit_code(self, pid: int, timeout_s: float) -> int | None:
        """The exit code of a fork that has ended (None if not reported within ``timeout_s``)."""
        self._wait_for(lambda: pid in self._exits, timeout_s)
        with self._cond:
            return self._exits.pop(pid, None)

    def close(self) -> None:
        with contextlib.suppress(OSError):  # the reader thread's recv returns; the peer sees EOF
            self._sock.shutdown(socket.SHUT_RDWR)
        with contextlib.suppress(OSError):
            self._sock.close()
        if self.process is not None:
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.process.wait(2.0)


_starter: WarmStart | None = None
_pending: WarmStart | None = None
"""Started or connected by :func:`prestart`, not yet waited for."""
_spawned: subprocess.Popen[bytes] | None = None
"""The resident warm start :func:`prestart` started (it connects to it later)."""
_starter_failed = ""
"""Why this process's warm start could not be started (then it is not tried again)."""
_starter_lock = threading.Lock()


def mode() -> str:
    """How motion processes start here: ``direct``, ``command`` or ``resident`` (see the
    module docstring)."""
    if switched_off(ENV_WARM_START):
        return "direct"
    return ("command" if os.environ.get(ENV_WARM_START, "").strip().lower() == PER_COMMAND
            else "resident")


def prestart() -> None:
    """Get the warm start going now and return at once. For this front end's own, its imports
    (about 2 s of one core) overlap the front end's own until a motion process is first asked
    for; the resident one is connected to, or started when there is none. A front end that
    will move the wrist calls it first thing; nothing is waited for here."""
    global _pending, _spawned, _starter_failed
    how = mode()
    if how == "direct":
        return
    with _starter_lock:
        if _starter is not None or _pending is not None or _spawned is not None \
                or _starter_failed:
            return
        try:
            path = resident.socket_path() if how == "resident" else None
            if path is None:
                _pending = WarmStart.own()
                return
            sock = resident.try_connect(path)
            if sock is not None:
                _pending = WarmStart(sock, None)
            else:
                _spawned = resident.spawn(path)
        except OSError as exc:
            _starter_failed = str(exc) or type(exc).__name__


def _resident_or_own(how: str) -> WarmStart:
    """The warm start to use now, ready: the one :func:`prestart` got going, else the
    resident (a fresh one when it was stale), else this front end's own."""
    global _pending, _spawned
    started, spawned, _pending, _spawned = _pending, _spawned, None, None
    path = resident.socket_path() if how == "resident" else None
    for _ in range(2):  # the second time: the resident found stale has freed its path
        if started is None and path is not None:
            with contextlib.suppress(OSError):
                started = WarmStart(resident.connect(path, spawned), None)
        if started is None:
            break
        try:
            started.await_ready()
            return started
        except NotSentError:
            if not started.stale:
                break
            started, spawned = None, None
    own = WarmStart.own()
    own.await_ready()
    return own


def _warm_start() -> WarmStart | None:
    """This process's warm start (started on first use, or by :func:`prestart`), or None when
    it is not to be used or cannot be."""
    global _starter, _starter_failed
    how = mode()
    if how == "direct":
        return None
    with _starter_lock:
        if _starter is not None and not _starter.alive:
            _starter.close()
            _starter = None
        if _starter is None and not _starter_failed:
            try:
                _starter = _resident_or_own(how)
            except OSError as exc:
                _starter_failed = str(exc) or type(exc).__name__
        return _starter


def start_direct(theirs: socket.socket) -> subprocess.Popen[bytes]:
    """``python -m spm_console.motion.server`` on ``theirs``, in a session of its own."""
    return subprocess.Popen(
        [sys.executable, "-m", "spm_console.motion.server", "--fd", str(theirs.fileno())],
        pass_fds=(theirs.fileno(),), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
        # its own session: a signal to the front end's process group (Ctrl-C, Ctrl-\, the
        # terminal closing, ``kill -- -PGID``, ``timeout``) reaches the front end, which
        # E-stops through this connection; the servo loop is never killed by it
        start_new_session=True)


def start_motion_process(theirs: socket.socket) -> MotionProcessHandle:
    """The motion process serving ``theirs`` (see the module docstring). OSError when the
    warm start took ``theirs`` but gave no motion process: never two processes on one socket."""
    starter = _warm_start()
    if starter is not None:
        try:
            return starter.fork(theirs)
        except NotSentError:
            pass  # the warm start is gone before it was asked: start this one directly
    return start_direct(theirs)


def fork_helper(module: str, stdin_fd: int, stdout_fd: int) -> ForkedProcess | None:
    """The helper ``module`` forked from this front end's warm start (its imports already
    done: milliseconds instead of about 0.6 s), or None when there is no warm start to ask or
    it refused (the caller then starts the helper as a process of its own)."""
    starter = _warm_start()
    if starter is None:
        return None
    try:
        return starter.fork_helper(module, stdin_fd, stdout_fd)
    except NotSentError:
        return None
