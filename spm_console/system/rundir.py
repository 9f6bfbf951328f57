"""This user's private runtime folder, and who asked for a motion process forked there.

The resident warm start (:mod:`spm_console.system.resident`) listens in this folder:
``$XDG_RUNTIME_DIR/spm-console`` when that is set, else ``/tmp/spm-console-UID``; created with
mode 0700 and used only while it is a real folder of this user that nobody else can open.

Beside its socket it notes, for each motion process it forked, the front end that asked
(``fork-PID``: the asker's pid, from the socket's peer credentials): a motion process's parent
is the resident, so the bus's lock names its front end from here
(:mod:`spm_console.devices.dynamixel.port_lock`).
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from pathlib import Path

#: Largest note read, bytes.
_MAX_NOTE = 32


def private_dir() -> Path | None:
    """The folder (created when missing), or None when it is not private: owned by another
    user, a link, open to others, or not creatable."""
    base = os.environ.get("XDG_RUNTIME_DIR", "")
    folder = (Path(base) / "spm-console" if base and os.path.isabs(base) and os.path.isdir(base)
              else Path(tempfile.gettempdir()) / f"spm-console-{os.getuid()}")
    try:
        folder.mkdir(mode=0o700, exist_ok=True)
        st = os.lstat(folder)
    except OSError:
        return None
    if not stat.S_ISDIR(st.st_mode) or st.st_uid != os.getuid() or st.st_mode & 0o077:
        return None
    return folder


def _note(folder: Path, pid: int) -> Path:
    return folder / f"fork-{pid}"


def note_front_end(folder: Path, pid: int, front_end: int) -> None:
    """Record that motion process ``pid`` serves the front end ``front_end``."""
    with contextlib.suppress(OSError):
        fd = os.open(_note(folder, pid), os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW
                     | os.O_CLOEXEC, 0o600)
        try:
            os.write(fd, str(front_end).encode())
        finally:
            os.close(fd)


def forget_front_end(folder: Path, pid: int) -> None:
    """The motion process ``pid`` has ended."""
    with contextlib.suppress(OSError):
        os.unlink(_note(folder, pid))


def front_end_of(pid: int) -> int | None:
    """The front end a resident's motion process ``pid`` serves, if noted here."""
    folder = private_dir()
    if folder is None:
        return None
    try:
        fd = os.open(_note(folder, pid), os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        text = os.read(fd, _MAX_NOTE).decode("ascii", "replace").strip()
    finally:
        os.close(fd)
    return int(text) if text.isdigit() else None
