"""The ``--json`` contract, command by command, as a user's script runs them: stdout is one
JSON value and nothing else, on success and on failure (then ``{"ok": false, ...}`` with the
exit code). Each command runs in a process of its own, so whatever a library prints on file
descriptor 1 would show here.

CI also runs this file in an environment resolved for the newest releases ``pyproject.toml``
allows (``make test-newest``): a new release of a dependency that prints breaks it there.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from spm_console.errors import ExitCode
from spm_console.report import paper_values as pv

pytestmark = pytest.mark.slow  # about 30 processes; CI's slow stage and make test-newest


def _deg(v: tuple[float, ...]) -> list[str]:
    return [f"{x:g}" for x in v]


def _run(argv: list[str], env: dict[str, str]) -> tuple[int, Any, str]:
    proc = subprocess.run([sys.executable, "-m", "spm_console", *argv], capture_output=True,
                          text=True, timeout=300, env=env)
    try:
        value = json.loads(proc.stdout)  # refuses anything before or after the one value
    except ValueError:
        pytest.fail(f"{' '.join(argv)}: stdout is not one JSON value:\n{proc.stdout[:2000]}"
                    f"\nstderr:\n{proc.stderr[-2000:]}")
    return proc.returncode, value, proc.stderr


def test_every_command_prints_one_json_value(tmp_path: Path) -> None:
    env = {**os.environ, "SPM_CONSOLE_CACHE": str(tmp_path / "cache"),
           "SPM_CONSOLE_LOGS": str(tmp_path / "logs")}
    mvn = tmp_path / "mvn.json"
    ok: list[list[str]] = [
        ["workspace", "build", "--force", "--json"],  # HiGHS solves the region's LPs
        ["workspace", "show", "--json"],
        ["workspace", "check", "--theta", "135", "135", "135", "--json"],
        ["workspace", "region", "--json"],
        ["fk", "--theta", "135", "135", "135", "--json"],
        ["ik", "--rpy", "5", "5", "5", "--json"],
        ["plan", "mvn", "--start", *_deg(pv.MVN_START_DEG), "--goal", *_deg(pv.MVN_GOAL_DEG),
         "--out", str(mvn), "--json"],
        ["plan", "mintime", "--start", *_deg(pv.MINTIME_START_DEG), "--goal",
         *_deg(pv.MINTIME_GOAL_DEG), "--json"],
        ["plan", "show", str(mvn), "--json"],
        ["home", "--sim", "--plant", "ideal", "--json"],
        ["execute", "--sim", "--plant", "ideal", "--plan", str(mvn), "--json"],
        ["latency", "--seconds", "0.2", "--json"],
        ["export", "urdf", "--out", str(tmp_path / "wrist.urdf"), "--json"],
        ["export", "mjcf", "--out", str(tmp_path / "wrist.xml"), "--json"],
    ]
    runs: dict[str, Any] = {}
    for argv in ok:
        code, value, err = _run(argv, env)
        assert code == 0, (argv, value, err[-2000:])
        runs[" ".join(argv[:2])] = value
    run_dir = runs["execute --sim"]["log_dir"]
    for argv in (["logs", "show", run_dir, "--json"], ["identify", "--run", run_dir, "--json"]):
        code, value, err = _run(argv, env)
        assert code == 0, (argv, value, err[-2000:])

    bad: list[list[str]] = [  # refused: each with its own exit code, never 1
        ["fk", "--theta", "135", "135", "nan", "--json"],
        ["ik", "--rpy", "5", "5", "--json"],
        ["workspace", "check", "--theta", "0", "0", "0", "--json"],
        ["plan", "mvn", "--start", "135", "135", "135", "--goal", "135", "135", "135",
          "--steps", "-3", "--json"],
        ["plan", "show", str(tmp_path / "missing.json"), "--json"],
        ["execute", "--sim", "--plan", str(tmp_path / "missing.json"), "--json"],
        ["logs", "show", str(tmp_path / "no-such-run"), "--json"],
        ["identify", "--csv", str(tmp_path / "missing.csv"), "--json"],
        ["latency", "--seconds", "-1", "--json"],
        ["fk", "--theta", "135", "135", "135", "--profile", str(tmp_path / "none.toml"),
          "--json"],
        ["no-such-command", "--json"],
        ["export", "urdf", "--out", str(tmp_path / "wrist.txt"), "--json"],
    ]
    for argv in bad:
        code, value, _ = _run(argv, env)
        assert isinstance(value, dict) and value["ok"] is False, (argv, value)
        assert code == value["exit_code"], (argv, code, value)
        assert code not in (ExitCode.OK, ExitCode.INTERNAL), (argv, value)
