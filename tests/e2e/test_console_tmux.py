"""The real entry point in a real terminal: tmux runs ``spm-console tui`` and the test
walks homing -> workspace -> plan -> execute by keystrokes, reading the screen with
``capture-pane``. Also: the 3D viewer's URL is shown, it listens on loopback only, and
its server goes away on quit and on SIGTERM; closing the terminal mid-motion stops the wrist."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from spm_console.motion.logs.runlog import list_runs
from tests.support.net_helpers import listening
from tests.support.paths import ROOT as PROJECT_ROOT
from tests.support.procfs import alive
from tests.support.terminal_helpers import assert_estopped

ROOT = PROJECT_ROOT
pytestmark = pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux is not installed")


class Tmux:
    """One private tmux server (its own socket) with one window running a command."""

    def __init__(self, cmd: list[str], env: dict[str, str], size: tuple[int, int] = (140, 42)) -> None:
        self.sock = f"spm-test-{uuid.uuid4().hex[:8]}"
        envs = [f"{k}={v}" for k, v in env.items()]
        # size the window first, then start the console in it: it reads its size at start
        self._tmux("-f", "/dev/null", "new-session", "-d", "-s", "t", "-x", str(size[0]),
                   "-y", str(size[1]), "sleep 600")
        self._tmux("set-option", "-t", "t", "window-size", "manual")
        self._tmux("resize-window", "-t", "t", "-x", str(size[0]), "-y", str(size[1]))
        self._tmux("respawn-pane", "-k", "-t", "t", "env", "-i", *envs, *cmd)

    def _tmux(self, *args: str) -> str:
        return subprocess.run(["tmux", "-L", self.sock, *args], capture_output=True, text=True,
                              check=True, timeout=10).stdout

    def screen(self) -> str:
        return self._tmux("capture-pane", "-p", "-t", "t")

    def keys(self, *keys: str) -> None:
        for k in keys:
            self._tmux("send-keys", "-t", "t", k)
            time.sleep(0.15)

    def wait_for(self, pattern: str, timeout_s: float = 30.0) -> str:
        t_end = time.monotonic() + timeout_s
        text = ""
        while time.monotonic() < t_end:
            text = self.screen()
            if re.search(pattern, text):
                return text
            time.sleep(0.1)
        raise AssertionError(f"{pattern!r} not on screen after {timeout_s} s:\n{text}")

    def pane_pid(self) -> int:
        return int(self._tmux("display-message", "-p", "-t", "t", "#{pane_pid}").strip())

    def alive(self) -> bool:
        return subprocess.run(["tmux", "-L", self.sock, "has-session", "-t", "t"],
                              capture_output=True).returncode == 0

    def kill(self) -> None:
        subprocess.run(["tmux", "-L", self.sock, "kill-server"], capture_output=True)

    def quit(self, timeout_s: float = 10.0) -> None:
        """q, then q again once the question is on screen, as a person reads before answering;
        asserts the console is gone within ``timeout_s``. Two keys sent back to back can reach a
        busy console in one read (an Escape and a q then arrive as alt+q)."""
        self.keys("q")
        self.wait_for(r"Quit the console\?")
        self.keys("q")
        t0 = time.monotonic()
        while self.alive() and time.monotonic() - t0 < timeout_s:
            time.sleep(0.1)
        assert not self.alive(), "the console did not quit on q"


@pytest.fixture
def env(tmp_path: Path, ws_cache_dir: Path) -> dict[str, str]:
    """The console's environment: its motions in simulated time paced at real time (the
    tests act while the wrist moves; a loaded machine slows the wrist, never races it)."""
    return {"SPM_CONSOLE_LOGS": str(tmp_path / "logs"), "SPM_CONSOLE_CACHE": str(ws_cache_dir),
            "TERM": "xterm-256color", "COLORTERM": "truecolor", "PATH": os.environ["PATH"],
            "HOME": os.environ.get("HOME", "/tmp"), "SPM_CONSOLE_CLOCK": "simulated:1"}


@pytest.fixture(scope="module")
def ws_cache_dir(tmp_path_factory: pytest.TempPathFactory, agile) -> Path:  # type: ignore[no-untyped-def]
    from tests.support.ws_helpers import cache_folder_holding

    return cache_folder_holding(agile, tmp_path_factory.mktemp("tmux-cache"))


@pytest.fixture
def tmux_console(env: dict[str, str]) -> Iterator[callable]:  # type: ignore[valid-type]
    made: list[Tmux] = []

    def start(*args: str) -> Tmux:
        t = Tmux([sys.executable, "-m", "spm_console", "tui", *args], env)
        made.append(t)
        return t

    yield start
    for t in made:
        t.kill()


def _moved(tmp_path: Path) -> list:  # type: ignore[type-arg]
    """The runs that moved the wrist (not the previews on its twin), oldest first."""
    return [r for r in list_runs(tmp_path / "logs") if not r.info.preview]


def _home_and_solve(t) -> None:  # type: ignore[no-untyped-def]
    """Home, load the workspace and solve the default MVN plan, key by key: each key waits
    for the screen it needs (a key sent early would be lost, or refused as busy: the hint is up
    before the connection is done)."""
    t.wait_for(r"press h to home")
    t.wait_for(r"connected: 3 servos answer")
    assert "Traceback" not in t.screen()
    t.keys("h")
    t.wait_for(r"Home the wrist\?")
    t.keys("y")
    t.wait_for(r"homed: executed")
    t.keys("3")
    t.wait_for(r"workspace ready")
    t.keys("4")
    t.wait_for(r"press s to solve")
    t.keys("s")
    t.wait_for(r"solved in .* Press 5 to execute")


def _start_execution(t) -> None:  # type: ignore[no-untyped-def]
    t.keys("5", "x")
    t.wait_for(r"Execute the plan\?")
    t.keys("y")


def _moving(t) -> None:  # type: ignore[no-untyped-def]
    """Until the wrist moves: the banner is up from the request on, the countdown only once
    the run's samples come (torque on; a loaded machine can take longer than 0.5 s to get
    there)."""
    t.wait_for(r"(?s)(?=.*E-STOP: press SPACE)(?=.*s to go)")
    time.sleep(0.3)


@pytest.mark.realtime  # the one walk through the console on the wall clock
def test_walk_home_plan_execute_by_keys(tmux_console, env, tmp_path) -> None:  # type: ignore[no-untyped-def]
    env["SPM_CONSOLE_CLOCK"] = "real"
    t = tmux_console("--sim", "--plant", "ideal", "--no-viewer")
    _home_and_solve(t)
    # the result panel may be painted a frame after the status line: wait for it, then check it
    screen = t.wait_for(r"N = 150 × 0\.02 s = 3\.00 s")
    assert "MVN" in screen and "N = 150 × 0.02 s = 3.00 s" in screen
    _start_execution(t)
    # the banner is up while it moves: one screen shows both (panels may paint a frame apart)
    live = t.wait_for(r"(?s)(?=.*E-STOP: press SPACE)(?=.*(s to go|executing))")
    assert "E-STOP: press SPACE" in live and ("s to go" in live or "executing" in live)
    t.wait_for(r"COMPLETED \(exit code 0\)", timeout_s=30)
    # banner gone, and the run's log named (the result panel may be painted a frame later)
    done = t.wait_for(r"^(?![\s\S]*E-STOP: press SPACE)[\s\S]*log: \S+", timeout_s=3)
    m = re.search(r"log: (\S+)", done)
    assert m is not None, done
    t.keys("6")
    t.wait_for(r"-execute")
    t.keys("enter")
    t.wait_for(r"outcome completed \(exit code 0\)")
    t.quit()
    assert [r.meta["outcome"] for r in _moved(tmp_path)] == ["completed", "completed"]


def _viewer_port(screen: str) -> int:
    m = re.search(r"3D view: http://127\.0\.0\.1:(\d+)/static/", screen)
    assert m is not None, screen
    return int(m.group(1))


def _wait_gone(port: int, timeout_s: float = 10.0) -> None:
    t_end = time.monotonic() + timeout_s
    while listening(port) and time.monotonic() < t_end:
        time.sleep(0.1)
    assert not listening(port), f"the viewer still listens on {port}"


def test_viewer_url_shown_loopback_only_and_stopped_on_quit(tmux_console) -> None:  # type: ignore[no-untyped-def]
    """Also: without --plant, the console drives the physical emulated wrist (its default)."""
    t = tmux_console("--sim")
    t.wait_for(r"physical wrist", timeout_s=30)
    screen = t.wait_for(r"3D view: http://127\.0\.0\.1:\d+/static/", timeout_s=30)
    port = _viewer_port(screen)
    addrs = listening(port)
    assert addrs and all(a in ("0100007F", "00000000000000000000000001000000") for a in addrs), addrs
    t.quit()
    _wait_gone(port)


@pytest.mark.realtime  # "the hold within two periods" is a claim on the wall clock
@pytest.mark.parametrize("sig", [
    signal.SIGTERM,
    pytest.param(signal.SIGINT, marks=pytest.mark.slow),
    pytest.param(signal.SIGHUP, marks=pytest.mark.slow),
    pytest.param(signal.SIGQUIT, marks=pytest.mark.slow),
], ids=lambda s: s.name)
def test_a_signal_to_its_group_mid_motion_stops_the_wrist_the_console_and_its_viewer(  # type: ignore[no-untyped-def]
        tmux_console, tmp_path, agile, sig) -> None:
    """``kill -SIG -- -PGID`` of the console's process group (a service stop, a shell's hang-up
    of its job): the console E-stops through the motion process, which the signal does not
    reach (its own session), then leaves; the hold is written within two periods."""
    t = tmux_console("--sim", "--plant", "ideal")
    port = _viewer_port(t.wait_for(r"3D view: http://127\.0\.0\.1:\d+/static/", timeout_s=30))
    _home_and_solve(t)
    _start_execution(t)
    _moving(t)
    runs = list_runs(tmp_path / "logs")
    loop_pid = int(runs[-1].meta["process"]["pid"])
    pid = t.pane_pid()
    os.killpg(pid, sig)
    _wait_gone(port)
    t0 = time.monotonic()
    while alive(pid) and time.monotonic() - t0 < 10:
        time.sleep(0.1)
    assert not alive(pid)
    runs = _moved(tmp_path)
    assert [r.meta["outcome"] for r in runs] == ["completed", "stopped"]
    assert_estopped(tmp_path / "logs", runs[-1].path, sig, agile.servo.ts_s, loop_pid)


@pytest.mark.realtime  # as above: the E-stop's latency is measured on the wall clock
def test_closing_the_terminal_mid_motion_stops_the_wrist_and_closes_the_log(  # type: ignore[no-untyped-def]
        tmux_console, tmp_path, agile) -> None:
    """The terminal goes away (tmux closes the pty: SIGHUP, as a dropped SSH session)."""
    t = tmux_console("--sim", "--plant", "ideal", "--no-viewer")
    _home_and_solve(t)
    _start_execution(t)
    _moving(t)
    pid = t.pane_pid()
    t.kill()  # the terminal closes under the console
    t0 = time.monotonic()
    while alive(pid) and time.monotonic() - t0 < 10:
        time.sleep(0.1)
    assert not alive(pid), "the console outlived its terminal"
    runs = _moved(tmp_path)
    assert [r.meta["outcome"] for r in runs] == ["completed", "stopped"]
    assert runs[-1].meta["exit_code"] == 20 and runs[-1].meta["message"] == "E-stop: signal SIGHUP"
    assert_estopped(tmp_path / "logs", runs[-1].path, signal.SIGHUP, agile.servo.ts_s,
                    int(runs[-1].meta["process"]["pid"]))



def test_walk_the_new_tools_in_a_real_terminal(tmux_console) -> None:  # type: ignore[no-untyped-def]
    """As a person at 80×24: the live servo table, a jog refused before homing, F-keys from
    inside a field, digits typed into a field staying there, `?` listing the keys."""
    t = tmux_console("--sim", "--plant", "ideal", "--no-viewer")
    t._tmux("resize-window", "-t", "t", "-x", "80", "-y", "24")
    t.wait_for(r"press h to home")
    t.wait_for(r"12\.0 V")  # the live status table: voltage read from the servos
    t.keys("+")  # jog before homing: refused, nothing moves
    t.wait_for(r"(?i)not homed|home it first|homed only")
    t.keys("F4")
    t.wait_for(r"steps N")
    t.keys("Tab")  # into the first field of the form, then type digits into it
    for _ in range(8):
        if "Fields" in t.screen():
            break
        time.sleep(0.1)
    t.keys("F2")  # an F-key switches from anywhere, even inside a field
    t.wait_for(r"Motor angles θ")
    t.keys("Tab", "5", "5")  # digits into a field never switch steps
    time.sleep(0.5)
    screen = t.screen()
    assert "Motor angles θ" in screen and "55" in screen  # still step 2, the digits typed
    t.keys("Escape")  # out of the field; a pause, or escape and ? reach it as alt+?
    time.sleep(0.5)
    t.keys("?")
    t.wait_for(r"esc or \? closes")
    assert "Traceback" not in t.screen()
    t.keys("Escape")
    t.wait_for(r"^(?![\s\S]*esc or \? closes)[\s\S]*Motor angles θ")  # help closed: step 2
    t.keys("0")  # step 0, commissioning: an empty port is refused, nothing starts
    t.wait_for(r"Servo bus")
    t.keys("s")
    t.wait_for(r"servo bus: empty")
    assert "Commission the wrist?" not in t.screen()
    t.quit()
