"""A moving command with ``--sim`` starts the emulated bus's process first thing, so that its
imports overlap the front end's own (spm_console.system.childproc.prespawn): used when the
bus is started, and ended with the command when it is not."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from spm_console.config.schema import Profile
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


def test_a_spare_started_under_another_environment_is_not_taken(
        agile: Profile, monkeypatch: pytest.MonkeyPatch) -> None:
    """The child reads its settings from its environment: a spare started before the
    environment changed (an in-process command before a console test, here real-time
    scheduling switched off since) is ended, and a child started under the new one serves."""
    monkeypatch.delenv("SPM_CONSOLE_REALTIME", raising=False)
    childproc.prespawn(EMULATOR)
    spare = childproc._spares[EMULATOR]
    monkeypatch.setenv("SPM_CONSOLE_REALTIME", "0")
    child = ChildProcess(EMULATOR, what="emulated servo bus")
    try:
        info = child.start(json.dumps({"profile": agile.model_dump(mode="json"),
                                       "faults": []}).encode())
        assert child._proc is not None and child._proc.pid != spare.pid
        assert info["realtime_granted"] is False and "SPM_CONSOLE_REALTIME=0" in info["realtime"]
    finally:
        child.stop()
    assert spare.wait(5) is not None  # ended, never served
    assert EMULATOR not in childproc._spares
