"""The settings in a real terminal: tmux runs ``spm-console tui``, the operator switches to
another profile and grid step by keys, the console restarts in the same terminal (the old
session closed), builds the new workspace with progress, and quits cleanly."""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import pytest

from tests.e2e.test_console_tmux import Tmux
from tests.support.procfs import descendants

pytestmark = pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux is not installed")


@pytest.mark.slow  # a whole real-time run (the slow set runs in CI as its own stage)
def test_switch_profile_and_grid_step_restarts_in_the_same_terminal(tmp_path: Path) -> None:
    # a warm start of the console's own: the processes of its sessions are its descendants
    env = {"SPM_CONSOLE_WARM_START": "command",
           "SPM_CONSOLE_LOGS": str(tmp_path / "logs"), "SPM_CONSOLE_CACHE": str(tmp_path / "c"),
           "SPM_CONSOLE_CONFIG": str(tmp_path / "config"), "TERM": "xterm-256color",
           "PATH": os.environ["PATH"], "HOME": os.environ.get("HOME", "/tmp")}
    t = Tmux([sys.executable, "-m", "spm_console", "tui", "--sim", "--plant", "ideal", "--no-viewer",
              "--grid-step", "5"], env)
    try:
        t.wait_for(r"press h to home")
        before = len(descendants(t.pane_pid()))
        assert before >= 3  # the warm start, the motion process and the emulated bus
        t.keys("C-o")
        t.wait_for(r"In use: profile agile_wrist .*grid step 5°")
        t.keys("Down")
        t.wait_for(r"coaxial_spm")
        t.keys("Enter", "BSpace", "1", "0", "Enter")  # 10°: a quick build
        t.wait_for(r"Restart with the new settings\?")
        assert "coaxial_spm" in t.screen()
        t.keys("y")
        # the notice wraps (at the top right, beside the servo table): its words, in order
        t.wait_for(r"(?s)Settings applied: profile \S*coaxial_spm\.toml,.*grid.*step 10°")
        screen = t.wait_for(r"press h to home")  # the new console starts at the connect step
        assert "profile coaxial_spm" in screen
        # the old session closed: its motion process and emulator are gone, not doubled
        assert len(descendants(t.pane_pid())) == before
        t.keys("3")
        screen = t.wait_for(r"workspace ready", timeout_s=120)
        assert "step 10°" in screen and "no cache file" in screen
        assert "Traceback" not in screen
        t.quit()
    finally:
        t.kill()
    assert any((tmp_path / "c").glob("workspace-coaxial_spm-10deg.npz"))
