"""A moving command shows what it does on its terminal (phase, bar, time, tracking error), and
nothing of it reaches a pipe, ``--json`` or ``--quiet``."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from spm_console.cli.main import main
from tests.support.terminal_helpers import Terminal

START = ["127.53", "83.23", "85.25"]
GOAL = ["66.80", "155.00", "131.48"]


@pytest.fixture(scope="module")
def plan(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("plans") / "p.json"
    assert main(["plan", "mvn", "--start", *START, "--goal", *GOAL, "--out", str(path)]) == 0
    return path


def _execute(plan: Path, logs: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "spm_console", "execute", "--sim", "--plan", str(plan),
            "--logs", str(logs), *extra]


@pytest.mark.parametrize("quiet", [False, True])
def test_execute_on_a_terminal_shows_its_progress(plan: Path, tmp_path: Path,
                                                  quiet: bool) -> None:
    env = dict(os.environ, COLUMNS="100", TERM="xterm-256color")
    term = Terminal(_execute(plan, tmp_path / "logs", *(["--quiet"] if quiet else [])), env)
    try:
        assert term.wait(120) == 0, term.output
    finally:
        term.kill()
    shown = term.output
    assert "completed:" in shown  # the summary, after the display is gone
    for words in ("homing", "plan ", "tracking error", " s left"):
        assert (words in shown) is not quiet, (words, shown[-2000:])


def test_a_pipe_gets_no_progress(plan: Path, tmp_path: Path) -> None:
    run = subprocess.run(_execute(plan, tmp_path / "logs"), capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    assert "tracking error" not in run.stderr and "\x1b[" not in run.stderr
    assert run.stdout.startswith("completed:")
