"""One owner per bus: an exclusive ``flock`` on the port, held by the process that opened it.

Two processes writing instructions on one Dynamixel bus interleave their goals and read each
other's replies, so a bus is opened by one process at a time. The lock is the kernel's
(``flock(LOCK_EX | LOCK_NB)``): it is released when its holder closes the port or ends, however
it ends, and a serial device is locked the way serial tools lock it (pyserial's
``exclusive=True`` takes the same lock), so they keep out of each other's way too.

* a serial device: the lock is taken on the open device itself;
* the emulated bus's socket (``unix:PATH``, which cannot be opened as a file): on ``PATH.lock``
  beside it, in the emulator's private folder.

A second opener is refused (:class:`~spm_console.errors.BadInputError`, exit 4) before it sends
anything, with the holder named: the process that holds the lock is found in ``/proc/locks``
by the file's device and inode, and when it is a motion process (a fork of the warm start)
the front end that started it is named instead (its parent, or for a fork of the resident warm
start, the front end noted in :mod:`spm_console.system.rundir`).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
from pathlib import Path

from spm_console.errors import BadInputError
from spm_console.system.rundir import front_end_of

#: Command lines of this product's internal processes: the holder named is the front end above.
_INTERNAL = ("spm_console.services.zygote", "spm_console.motion.server")

#: How far up the parent chain the front end is looked for.
_MAX_PARENTS = 4


def lock_file_of_socket(path: str) -> str:
    """The lock file of the emulated bus's socket at ``path``."""
    return path + ".lock"


def open_socket_lock(path: str) -> int:
    """Open (create) the lock file of the socket at ``path``; its descriptor (close-on-exec)."""
    lock = lock_file_of_socket(path)
    try:
        return os.open(lock, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NOFOLLOW, 0o600)
    except OSError as exc:
        raise BadInputError(f"cannot lock the bus socket {path}: {lock}: "
                            f"{exc.strerror or exc}") from None


def take(fd: int, port: str, path: str) -> None:
    """Lock ``fd`` (an open ``path``) for this process alone; BadInputError naming the holder
    when another process has the bus."""
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN):
            raise BadInputError(f"cannot lock the bus {port}: {exc.strerror or exc}") from None
        raise BadInputError(f"the bus {port} is in use by {holder_of(path)}: one front end "
                            "drives a bus at a time; end that one first (nothing was sent)"
                            ) from None


def holder_of(path: str) -> str:
    """Who holds the flock on ``path``, in words ("process 123 (spm-console execute …)")."""
    pid = _lock_pid(path)
    if pid is None:
        return "another process"
    shown = pid
    for _ in range(_MAX_PARENTS):  # a motion process: name the front end that started it
        if not any(mark in _cmdline(shown) for mark in _INTERNAL):
            break
        front_end = front_end_of(shown)  # forked by the resident warm start: noted there
        if front_end is not None:
            shown = front_end
            break
        parent = _ppid(shown)
        if parent is None or parent <= 1:
            break
        shown = parent
    cmd = _cmdline(shown)
    return f"process {shown}" + (f" ({cmd})" if cmd else "")


def _lock_pid(path: str) -> int | None:
    """The pid holding a flock on ``path`` according to ``/proc/locks`` (None if not found)."""
    try:
        st = os.stat(path)
        text = Path("/proc/locks").read_text()
    except OSError:
        return None
    want = (os.major(st.st_dev), os.minor(st.st_dev), st.st_ino)
    for line in text.splitlines():
        parts = line.split()
        if len(parts) < 6 or parts[1] == "->" or parts[1] != "FLOCK":  # "->": a waiter
            continue
        with contextlib.suppress(ValueError):
            major, minor, inode = parts[5].split(":")
            if (int(major, 16), int(minor, 16), int(inode)) == want:
                return int(parts[4])
    return None


def _cmdline(pid: int) -> str:
    try:
        raw = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return ""
    words = [w.decode(errors="replace") for w in raw.split(b"\0") if w]
    if words:
        words[0] = os.path.basename(words[0])
    if len(words) > 1 and words[0].startswith("python") and words[1] != "-m":
        words = words[1:]  # "python .venv/bin/spm-console …": the script and its arguments
        words[0] = os.path.basename(words[0])
    return " ".join(words)[:200]


def _ppid(pid: int) -> int | None:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        return int(stat.rsplit(")", 1)[1].split()[1])
    except (OSError, ValueError, IndexError):
        return None
