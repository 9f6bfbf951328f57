"""Two front ends on one bus: while one drives the wrist, the second is refused (exit 4) before
it sends anything, naming the first; the first completes undisturbed."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from spm_console.cli.main import main
from spm_console.errors import ExitCode

pytestmark = pytest.mark.realtime  # an emulated bus on the wall clock (see tests/conftest.py)

START = ["127.53", "83.23", "85.25"]
GOAL = ["66.80", "155.00", "131.48"]


def _cli(*argv: str, logs: Path) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "spm_console", *argv, "--logs", str(logs)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, PYTHONUNBUFFERED="1"))


def _events(folder: Path) -> list[str]:
    return [json.loads(line)["event"] for f in folder.rglob("events.jsonl")
            for line in f.read_text().splitlines()]


def test_a_second_front_end_on_a_driven_bus_is_refused(tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    plan = tmp_path / "p.json"
    assert main(["plan", "mvn", "--start", *START, "--goal", *GOAL, "--out", str(plan)]) == 0
    capsys.readouterr()
    emu = subprocess.Popen([sys.executable, "-m", "spm_console", "emulate", "--json", "--link",
                            "socket"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                           env=dict(os.environ, PYTHONUNBUFFERED="1"))
    first: subprocess.Popen[str] | None = None
    try:
        assert emu.stdout is not None
        port = json.loads(emu.stdout.readline())["port"]
        first_logs, second_logs = tmp_path / "first", tmp_path / "second"
        first = _cli("execute", "--plan", str(plan), "--port", port, "--json", logs=first_logs)
        deadline = time.monotonic() + 60
        while "torque_on" not in _events(first_logs):  # the first one drives the wrist
            assert first.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        second = _cli("execute", "--plan", str(plan), "--port", port, "--json", logs=second_logs)
        out, err = second.communicate(timeout=60)
        assert second.returncode == ExitCode.BAD_INPUT, err
        reply = json.loads(out)
        assert f"is in use by process {first.pid} (python" in reply["error"]
        assert "-m spm_console execute --plan" in reply["error"]
        assert "Traceback" not in err
        assert "torque_on" not in _events(second_logs) and "start" not in _events(second_logs)
        out, err = first.communicate(timeout=60)
        assert first.returncode == 0, err
        assert json.loads(out)["outcome"] == "completed"
    finally:
        for proc in (first, emu):
            if proc is not None and proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
                try:
                    proc.wait(10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
