"""The resident warm start: where it listens, when it is stale, how a front end reaches it.

One resident warm start (:mod:`spm_console.services.zygote` ``--listen``) serves each user
and installation: its socket is ``warm-KEY.sock`` in a private folder
(:func:`spm_console.system.rundir.private_dir`), where
KEY digests the interpreter, its flags, ``sys.path`` and this package's folder, so two
installations (or two checkouts) never share one. The first front end that finds none starts
it, detached (its own session, the same ``sys.path``); an exclusive lock on ``warm-KEY.lock``
keeps it single; it writes its tracebacks, if any, to ``warm-KEY.log``.

**Stale-code rule.** The resident stamps every file it imported and every ``.py`` file of
this package (path, size, mtime, inode) once its imports are done, and checks the stamp on
every connection: after an update it retires at once and the front end starts a fresh one.

**Lifetime.** It ends :data:`IDLE_DEFAULT_S` after its last front end disconnected and its
last motion process ended (``SPM_CONSOLE_WARM_START_IDLE_S``, bounded to
[:data:`IDLE_MIN_S`, :data:`IDLE_MAX_S`]), on SIGTERM (once its motion processes have ended),
or when stale. ``spm-console warm-start --stop`` asks it to end.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import math
import os
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import spm_console
from spm_console.system.rundir import private_dir

#: Environment variable: seconds a resident warm start stays without use.
ENV_IDLE = "SPM_CONSOLE_WARM_START_IDLE_S"
IDLE_DEFAULT_S = 900.0
IDLE_MIN_S = 1.0
IDLE_MAX_S = 86400.0
#: Seconds a front end waits for a resident it started (or saw starting) to listen.
LISTEN_TIMEOUT_S = 5.0
#: The longest socket path used (``sun_path`` holds 108 bytes with its terminator).
MAX_PATH_BYTES = 100
#: A resident's log is emptied when it is found larger than this at a start, bytes.
MAX_LOG_BYTES = 1 << 20
PACKAGE_DIR = Path(spm_console.__file__).resolve().parent


def bounded_idle(value: float) -> float:
    """``value`` within [IDLE_MIN_S, IDLE_MAX_S]; the default for a non-number."""
    if not math.isfinite(value):
        return IDLE_DEFAULT_S
    return min(max(value, IDLE_MIN_S), IDLE_MAX_S)


def idle_from_env() -> float:
    """The idle time asked for in the environment (bounded; the default when unreadable)."""
    try:
        return bounded_idle(float(os.environ.get(ENV_IDLE, "").strip() or IDLE_DEFAULT_S))
    except ValueError:
        return IDLE_DEFAULT_S


def installation_key() -> str:
    """What makes two front ends able to share a resident: interpreter, flags, path, package."""
    ident = json.dumps([sys.executable, repr(sys.flags), sys.path, str(PACKAGE_DIR)])
    return hashlib.sha256(ident.encode()).hexdigest()[:16]


def socket_path() -> str | None:
    """The resident's socket for this installation, or None when none can be used."""
    folder = private_dir()
    if folder is None:
        return None
    path = str(folder / f"warm-{installation_key()}.sock")
    return path if len(os.fsencode(path)) <= MAX_PATH_BYTES else None


def _stat(path: str) -> tuple[int, int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_size, st.st_mtime_ns, st.st_ino


def _package_sources() -> list[str]:
    return [str(p) for p in PACKAGE_DIR.rglob("*.py")]


@dataclass(frozen=True)
class CodeStamp:
    """The files a warm start's code came from, as they were when it took them."""

    files: dict[str, tuple[int, int, int] | None]

    @classmethod
    def now(cls) -> CodeStamp:
        paths = {f for m in list(sys.modules.values())
                 if isinstance(f := getattr(m, "__file__", None), str)}
        paths.update(_package_sources())
        return cls({p: _stat(p) for p in sorted(paths)})

    def changed(self) -> str:
        """"" when every file is as stamped (and this package has no new one), else one
        that is not."""
        for path, was in self.files.items():
            if _stat(path) != was:
                return path
        for path in _package_sources():
            if path not in self.files:
                return path
        return ""


class Listener:
    """The resident's listening socket and the lock that keeps it single."""

    def __init__(self, path: str, sock: socket.socket, lock_fd: int) -> None:
        self.path = path
        self.folder = Path(path).parent
        self.sock = sock
        self._lock_fd = lock_fd
        self._ino = os.stat(path).st_ino
        self._released = False

    @classmethod
    def bind(cls, path: str) -> Listener | None:
        """Listen on ``path``; None when another resident holds it (or it cannot be bound)."""
        try:
            lock_fd = os.open(path[: -len(".sock")] + ".lock",
                              os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NOFOLLOW, 0o600)
        except OSError:
            return None
        try:
            fcntl.flock(lock_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            with contextlib.suppress(FileNotFoundError):
                os.unlink(path)  # a socket left by one that was killed
            sock = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
            try:
                sock.bind(path)
                sock.listen(16)
            except OSError:
                sock.close()
                raise
        except OSError:
            os.close(lock_fd)
            return None
        return cls(path, sock, lock_fd)

    def accept(self) -> socket.socket | None:
        """The next front end of this user (None: another user's, or none after all)."""
        try:
            conn, _ = self.sock.accept()
        except OSError:
            return None
        creds = conn.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, struct.calcsize("3i"))
        _pid, uid, _gid = struct.unpack("3i", creds)
        if uid != os.getuid():
            conn.close()
            return None
        return conn

    @staticmethod
    def peer_pid(conn: socket.socket) -> int:
        """The pid of the front end at the other end of ``conn`` (when it connected)."""
        return int(struct.unpack("3i", conn.getsockopt(
            socket.SOL_SOCKET, socket.SO_PEERCRED, struct.calcsize("3i")))[0])

    def release(self) -> None:
        """Stop listening, free the path (if still ours) and the lock: a fresh resident may
        start at once."""
        if self._released:
            return
        self._released = True
        self.sock.close()
        st = _stat(self.path)
        if st is not None and st[2] == self._ino:
            with contextlib.suppress(OSError):
                os.unlink(self.path)
        os.close(self._lock_fd)

    def close_in_fork(self) -> None:
        """In a fork: drop the copies of the socket and the lock (the lock stays the
        resident's alone)."""
        if not self._released:
            self.sock.close()
            os.close(self._lock_fd)


def spawn(path: str) -> subprocess.Popen[bytes]:
    """Start the resident for ``path``, detached, with this front end's ``sys.path``."""
    log = path[: -len(".sock")] + ".log"
    fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_APPEND | os.O_NOFOLLOW | os.O_CLOEXEC,
                 0o600)
    try:
        if os.fstat(fd).st_size > MAX_LOG_BYTES:
            os.ftruncate(fd, 0)
        code = ("import sys, json; sys.path[:] = json.loads(sys.argv.pop(1)); "
                "from spm_console.services.zygote import main; raise SystemExit(main())")
        proc = subprocess.Popen(
            [sys.executable, "-c", code, json.dumps(sys.path), "--listen", path,
             "--idle", repr(idle_from_env())],
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=fd, cwd="/",
            start_new_session=True)
    finally:
        os.close(fd)
    threading.Thread(target=proc.wait, daemon=True, name="spm-resident-reaper").start()
    return proc


def try_connect(path: str) -> socket.socket | None:
    """A connection to the resident listening at ``path``; None when none listens. OSError
    when the one listening is another user's."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    try:
        sock.connect(path)
        creds = sock.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, struct.calcsize("3i"))
        if struct.unpack("3i", creds)[1] != os.getuid():
            raise PermissionError(f"{path} is served by another user")
    except (FileNotFoundError, ConnectionRefusedError):
        sock.close()
        return None
    except OSError:
        sock.close()
        raise
    return sock


def connect(path: str, started: subprocess.Popen[bytes] | None = None) -> socket.socket:
    """A connection to the resident at ``path``, started here when there is none (``started``:
    already started by this front end). OSError when none listens within
    :data:`LISTEN_TIMEOUT_S` (or the one started here ended at its start)."""
    deadline = time.monotonic() + LISTEN_TIMEOUT_S
    while True:
        sock = try_connect(path)
        if sock is not None:
            return sock
        if started is None:
            started = spawn(path)
        elif started.poll() is not None and started.returncode != 0:
            raise OSError(f"the resident warm start ended at its start (see {path[:-5]}.log)")
        if time.monotonic() > deadline:
            raise OSError("the resident warm start did not listen in time")
        time.sleep(0.01)


def running(path: str) -> int | None:
    """The pid of this user's resident listening at ``path``, or None when none does."""
    try:
        sock = try_connect(path)
    except OSError:
        return None
    if sock is None:
        return None
    with sock:
        return int(struct.unpack("3i", sock.getsockopt(
            socket.SOL_SOCKET, socket.SO_PEERCRED, struct.calcsize("3i")))[0])


def stop(path: str, timeout_s: float = 10.0) -> int | None:
    """Ask the resident at ``path`` to end (SIGTERM: it ends once its motion processes have);
    its pid, or None when none runs. Waits up to ``timeout_s`` for its socket to go."""
    pid = running(path)
    if pid is None:
        return None
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, signal.SIGTERM)
    deadline = time.monotonic() + timeout_s
    while os.path.exists(path) and time.monotonic() < deadline:
        time.sleep(0.02)
    return pid
