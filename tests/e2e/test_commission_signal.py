"""A stop signal mid-commissioning (SIGINT while a servo is being nudged, on the physical twin
wired as built): the nudge stops, the servos' PWM Limits are restored, the wrist holds where
it stopped (torque on), the command exits 20 (an E-stop) and the commissioning's run log is
closed as ``stopped``, with its nudges, its IMU readings and an MCAP with ``/imu``."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from mcap.reader import make_reader

from spm_console.errors import ExitCode
from spm_console.motion.logs.runlog import load_run
from tests.support.paths import ROOT

pytestmark = pytest.mark.realtime  # an emulated bus on the wall clock (see tests/conftest.py)

AGILE = ROOT / "profiles" / "agile_wrist.toml"
TWIN = ROOT / "tests" / "data" / "as_built" / "twin.toml"


@pytest.fixture
def twin() -> Iterator[dict[str, object]]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "spm_console", "emulate", "--plant", "physical", "--as-built",
         str(TWIN), "--imu", "--jig", "--link", "socket", "--duration", "300", "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    head = json.loads(proc.stdout.readline())
    yield head
    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=30)


def _register(port: str, name: str) -> dict[str, int]:
    done = subprocess.run([sys.executable, "-m", "spm_console", "servo", "read", "--port", port,
                           "--register", name, "--ids", "1", "2", "3", "--json"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    return {str(k): int(v) for k, v in json.loads(done.stdout)["values"].items()}


def test_sigint_mid_nudge_holds_the_wrist_and_closes_the_log(twin: dict[str, object],
                                                             tmp_path: Path) -> None:
    logs = tmp_path / "logs"
    before = _register(str(twin["port"]), "pwm_limit")
    proc = subprocess.Popen(
        [sys.executable, "-m", "spm_console", "commission", "--profile", str(AGILE), "--port",
         str(twin["port"]), "--imu-port", str(twin["imu_port"]), "--jig", "--no-imu-fit",
         "--out", str(tmp_path / "built.toml"), "--logs", str(logs), "--json"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=dict(os.environ, PYTHONUNBUFFERED="1"))
    assert proc.stderr is not None
    for line in proc.stderr:  # the stage lines: the first nudge has begun
        if "map: nudging servo id" in line:
            break
    else:
        raise AssertionError(f"no nudge began (exit {proc.wait(30)})")
    time.sleep(0.3)  # inside the nudge's ramp (1.8° at 4°/s)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    reply = json.loads(out.splitlines()[-1])
    assert proc.returncode == int(ExitCode.STOP_ESTOP), (reply, err[-2000:])
    assert reply["ok"] is False and "SIGINT" in reply["error"]
    assert not (tmp_path / "built.toml").exists()

    (run_dir,) = [p for p in logs.iterdir() if p.name.endswith("-commission")]
    run = load_run(run_dir)
    assert run.meta["outcome"] == "stopped" and run.meta["end_time"]
    assert run.meta["exit_code"] == int(ExitCode.STOP_ESTOP)
    names = [e["event"] for e in run.events]
    assert "nudge" in names and names[-1] == "stopped"
    nudge = next(e for e in run.events if e["event"] == "nudge")
    assert nudge["stopped"].startswith("stopped: ")  # the SIGINT's E-stop ended the ramp
    with (run_dir / "run.mcap").open("rb") as fh:
        topics = {ch.topic for ch in make_reader(fh).get_summary().channels.values()}
    assert {"/imu", "/spm/events"} <= topics
    assert run.meta["stats"]["imu_rows"] > 0

    port = str(twin["port"])
    assert _register(port, "torque_enable") == {"1": 1, "2": 1, "3": 1}  # holding
    assert _register(port, "pwm_limit") == before  # restored, not left at the nudges' limit
