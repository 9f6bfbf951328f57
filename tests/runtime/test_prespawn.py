"""A moving command with ``--sim`` starts the emulated bus's process first thing, so that its
imports overlap the front end's own (spm_console.system.childproc.prespawn): used when the
bus is started, and ended with the command when it is not."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from spm_console.system import childproc
from spm_console.system.childproc import ChildProcess

EMULATOR = "spm_console.devices.emulator.child"


def _children_of(pid: int) -> list[int]:
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            cmd = Path(f"/proc/{entry}/cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if EMULATOR.encode() in cmd and str(pid).encode() in cmd:
            found.append(int(entry))
    return found


def test_the_spare_is_the_child_started_next() -> None:
    childproc.prespawn(EMULATOR)
    spare = childproc._spares[EMULATOR]
    child = ChildProcess(EMULATOR, what="emulated servo bus")
    try:
        info = child.start(json.dumps({"profile": {}, "faults": []}).encode())
    except childproc.HelperProcessError as exc:  # an empty profile is refused: by the spare
        assert "profile" in exc.message
        assert spare.wait(5) == 1
    else:
        raise AssertionError(f"an empty profile was taken: {info}")
    assert EMULATOR not in childproc._spares


def test_an_unused_spare_ends_with_its_command(tmp_path: Path) -> None:
    """The plan file is missing: the command ends before any bus is started."""
    proc = subprocess.Popen([sys.executable, "-m", "spm_console", "execute", "--sim", "--plan",
                             str(tmp_path / "missing.json"), "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, _ = proc.communicate(timeout=60)
    assert proc.returncode != 0 and json.loads(out.splitlines()[-1])["ok"] is False
    assert _children_of(proc.pid) == []
