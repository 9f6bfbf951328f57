"""What /proc says of a process: its parent, and whether it still runs."""

from __future__ import annotations

from pathlib import Path


def parent_pid(pid: int) -> int:
    """The parent's pid of ``pid`` (field 4 of /proc/PID/stat, after the command's ")")."""
    return int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])


def alive(pid: int) -> bool:
    """The process exists and is not a zombie."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False
