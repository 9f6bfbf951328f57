"""Who writes a run log, and whether that process still lives (``killed`` runs).

A run log records its writer as ``{"pid", "host", "boot_id", "start_ticks"}``:
the pid alone is not enough, because pids are reused — after a reboot (``boot_id``
differs) or on a busy machine (the same pid, but a process started at another
time: ``start_ticks``, field 22 of ``/proc/PID/stat``, clock ticks since boot).
:func:`writer_alive` compares a record with the running system; it answers
``None`` ("cannot tell") for a log written on another host, so such a run is never
called ``killed`` by mistake. Linux gives the full answer; elsewhere the pid check
only (``boot_id`` and ``start_ticks`` are then ``None``).
"""

from __future__ import annotations

import os
import socket
from pathlib import Path

BOOT_ID = Path("/proc/sys/kernel/random/boot_id")


def _boot_id() -> str | None:
    try:
        return BOOT_ID.read_text().strip() or None
    except OSError:
        return None


def _stat(pid: int) -> tuple[str, int] | None:
    """(state, start time in clock ticks since boot) of a process, from /proc; None if absent."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    # "pid (comm) state ppid ..." — comm may hold spaces and parentheses: split after the last ')'
    fields = text[text.rfind(")") + 2:].split()
    try:
        return fields[0], int(fields[19])
    except (IndexError, ValueError):
        return None


def current_process() -> dict[str, object]:
    """The record of this process (stored in ``meta.json`` as ``process``)."""
    st = _stat(os.getpid())
    return {"pid": os.getpid(), "host": socket.gethostname(), "boot_id": _boot_id(),
            "start_ticks": None if st is None else st[1]}


def writer_alive(record: object) -> bool | None:
    """Is the process described by ``record`` still running? None when this cannot be told
    (no record, another host)."""
    if not isinstance(record, dict) or not isinstance(record.get("pid"), int) or record["pid"] <= 0:
        return None  # (kill(0) or kill(-n) would reach a whole process group)
    if record.get("host") != socket.gethostname():
        return None
    boot = _boot_id()
    if record.get("boot_id") and boot and record["boot_id"] != boot:
        return False  # the machine rebooted since: every process of that boot is gone
    pid = int(record["pid"])
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass  # exists, owned by someone else
    st = _stat(pid)
    if st is None:
        return True  # no /proc (not Linux): the pid exists, that is all we know
    state, ticks = st
    if state in ("Z", "X"):  # a zombie has ended; only its exit status waits for its parent
        return False
    start = record.get("start_ticks")
    return start is None or start == ticks
