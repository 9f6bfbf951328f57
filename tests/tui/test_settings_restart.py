"""``spm-console tui`` restarts the console with the settings the operator applied: each app
is closed before the next one is built, for the new profile file and grid step."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import pytest

from spm_console.cli.tui import cmd_tui, run_consoles
from spm_console.tui.screens.settings import SwitchRequest
from tests.conftest import ROOT

AGILE = ROOT / "profiles" / "agile_wrist.toml"
COAXIAL = ROOT / "profiles" / "coaxial_spm.toml"


class FakeApp:
    """Exits with a scripted result; records when it ran and was closed."""

    def __init__(self, events: list[str], name: str, result: Any) -> None:
        self.events, self.name, self.result = events, name, result

    def run(self) -> Any:
        self.events.append(f"run {self.name}")
        if isinstance(self.result, BaseException):
            raise self.result
        return self.result

    def shutdown(self) -> None:
        self.events.append(f"shutdown {self.name}")


def test_the_loop_restarts_with_each_request_until_an_exit_code() -> None:
    events: list[str] = []
    results = [SwitchRequest(COAXIAL, 3.0), SwitchRequest(AGILE, 1.0), 0]
    calls: list[tuple[Path, float | None, str]] = []

    def factory(path: Path, step: float | None, note: str, kept: Any) -> FakeApp:
        assert kept is None  # the settings keep no workspace
        calls.append((path, step, note))
        events.append(f"build {len(calls)}")
        return FakeApp(events, str(len(calls)), results[len(calls) - 1])

    assert run_consoles(AGILE, None, factory) == 0
    assert [(p, s) for p, s, _ in calls] == [(AGILE, None), (COAXIAL, 3.0), (AGILE, 1.0)]
    assert calls[0][2] == ""
    assert "coaxial_spm.toml" in calls[1][2] and "grid step 3°" in calls[1][2]
    # each console is closed before the next one is built
    assert events == ["build 1", "run 1", "shutdown 1", "build 2", "run 2", "shutdown 2",
                      "build 3", "run 3", "shutdown 3"]


def test_a_request_passes_its_note_and_kept_workspace_to_the_next_console() -> None:
    """The identification's request: its own note, and the workspace it kept."""
    kept = object()
    results = [SwitchRequest(AGILE, 2.0, why="Identified servo model in use", kept=kept), 0]  # type: ignore[arg-type]
    calls: list[tuple[str, Any]] = []

    def factory(path: Path, step: float | None, note: str, k: Any) -> FakeApp:
        calls.append((note, k))
        return FakeApp([], "a", results[len(calls) - 1])

    assert run_consoles(AGILE, None, factory) == 0
    assert calls == [("", None), ("Identified servo model in use", kept)]


def test_the_loop_returns_the_exit_code_and_closes_on_a_crash() -> None:
    events: list[str] = []
    assert run_consoles(AGILE, 2.0, lambda p, s, n, k: FakeApp(events, "a", 20)) == 20
    events.clear()
    with pytest.raises(RuntimeError):
        run_consoles(AGILE, 2.0, lambda p, s, n, k: FakeApp(events, "a", RuntimeError("x")))
    assert events == ["run a", "shutdown a"]


def test_cmd_tui_builds_each_console_for_the_requested_profile_and_grid_step(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    import spm_console.tui.app as tui_app

    built: list[dict[str, Any]] = []
    results = [SwitchRequest(COAXIAL, 3.0), 0]
    events: list[str] = []

    def fake_make_app(profile: Any, **kw: Any) -> FakeApp:
        built.append({"name": profile.name, "step": profile.workspace.step_deg, **kw})
        return FakeApp(events, profile.name, results[len(built) - 1])

    monkeypatch.setattr(tui_app, "make_app", fake_make_app)
    args = argparse.Namespace(profile=str(AGILE), grid_step=1.0, port=None, sim=True,
                              no_viewer=True, logs=tmp_path / "logs", cache_dir=tmp_path / "c")
    assert cmd_tui(args) == 0
    assert [(b["name"], b["step"], b["profile_path"]) for b in built] == [
        ("agile_wrist", 1.0, AGILE), ("coaxial_spm", 3.0, COAXIAL)]
    assert all(b["sim"] and b["port"] is None and b["cache_dir"] == tmp_path / "c"
               for b in built)
    assert built[1]["note"].startswith("Settings applied")
    assert events == ["run agile_wrist", "shutdown agile_wrist", "run coaxial_spm",
                      "shutdown coaxial_spm"]


def test_a_thread_left_running_after_the_console_closed_does_not_keep_the_process() -> None:
    """A terminal that went away can leave the UI library's input thread looping: once the
    console has closed, the process ends with the console's exit code instead of waiting."""
    import subprocess
    import sys

    code = (
        "import threading, time\n"
        "from spm_console.cli.tui import end_if_threads_linger\n"
        "before = set(threading.enumerate())\n"
        "threading.Thread(target=lambda: time.sleep(600), name='stuck').start()\n"
        "end_if_threads_linger(20, before, wait_s=0.2)\n"
        "print('not reached')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 20 and "not reached" not in out.stdout
    # a thread that was already there (an in-process caller's) is not the console's
    code = code.replace("before = set(threading.enumerate())\n", "").replace(
        "end_if_threads_linger(20, before", "end_if_threads_linger(20, set(threading.enumerate())")
    out = subprocess.run([sys.executable, "-c", code.replace("sleep(600)", "sleep(1)")],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and "not reached" in out.stdout
