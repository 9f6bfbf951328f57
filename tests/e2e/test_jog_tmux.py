"""The live jog in a real terminal (tmux, ``spm-console tui``): home, start the jog from step
5, move the target with the arrow keys, end it with esc (completed), start again, stop it
with SPACE (exit 20)."""

from __future__ import annotations

import pytest

from spm_console.motion.logs.runlog import list_runs
from tests.e2e.test_console_tmux import env, pytestmark, tmux_console, ws_cache_dir  # noqa: F401


@pytest.mark.slow  # a whole real-time run (the slow set runs in CI as its own stage)
def test_walk_a_live_jog_by_keys(tmux_console, tmp_path) -> None:  # type: ignore[no-untyped-def]  # noqa: F811
    t = tmux_console("--sim", "--plant", "ideal", "--no-viewer")
    t.wait_for(r"press h to home")
    t.keys("5", "j")  # not homed: refused
    t.wait_for(r"the wrist is not homed: press 1, then h")
    t.keys("1")
    t.wait_for(r"press h to home")
    t.keys("h")
    t.wait_for(r"Home the wrist\?")
    t.keys("y")
    t.wait_for(r"homed: executed")
    t.keys("5", "j")
    t.wait_for(r"live: move the target", timeout_s=60)
    assert "E-STOP: press SPACE" in t.screen()
    t.keys("m", "Right", "Right", "Up")  # per joint, 1° steps
    t.wait_for(r"target: +θ = \[137\.00, 136\.00, 135\.00\]°")
    t.wait_for(r"in the loop: θ = \[137\.00, 136\.00, 135\.00\]°")
    t.keys("Escape")
    done = t.wait_for(r"COMPLETED \(exit code 0\)", timeout_s=30)
    assert "live jog: " in done and "Traceback" not in done
    t.keys("j")
    t.wait_for(r"live: move the target", timeout_s=60)
    t.keys("Left", "Left", "Space")
    t.wait_for(r"STOPPED \(exit code 20\)", timeout_s=30)
    t.quit()
    runs = list_runs(tmp_path / "logs")
    assert [r.meta["kind"] for r in runs][-2:] == ["follow", "follow"]
    assert sorted(r.meta["outcome"] for r in runs if r.meta["kind"] == "follow") == [
        "completed", "stopped"]
