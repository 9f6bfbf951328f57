"""The resident warm start (spm_console.system.resident, spm_console.services.zygote ``--listen``): one per user
and installation, it outlives the command that started it, forks each motion process with
the asking front end's environment, umask and CPU set, and ends when idle, on SIGTERM once
its motion processes have ended, and when the code it imported changed on disk."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from spm_console.config.schema import Profile
from spm_console.devices.emulator.bus import EmulatorHandle, start_emulator
from spm_console.errors import SpmError
from spm_console.services import warm_start
from spm_console.services.client import MotionClient
from spm_console.system import resident
from tests.support.procfs import alive, parent_pid
from tests.support.terminal_helpers import wait_until

ROOT = Path(__file__).resolve().parents[2]
PROFILE = str(ROOT / "profiles" / "agile_wrist.toml")




def _umask_of(pid: int) -> int:
    with open(f"/proc/{pid}/status") as f:
        return next(int(line.split()[1], 8) for line in f if line.startswith("Umask:"))


@pytest.fixture
def run_dir(monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """A private runtime folder (short: a socket path), the resident mode, this process's warm
    start forgotten; at the end, the resident is stopped and must be gone."""
    folder = tempfile.mkdtemp(prefix="spm-rt-", dir="/tmp")
    monkeypatch.setenv("XDG_RUNTIME_DIR", folder)
    monkeypatch.delenv(warm_start.ENV_WARM_START, raising=False)
    for name, value in (("_starter", None), ("_pending", None), ("_spawned", None),
                        ("_starter_failed", "")):
        monkeypatch.setattr(warm_start, name, value)
    try:
        yield folder
    finally:
        if warm_start._starter is not None:
            warm_start._starter.close()
        path = resident.socket_path()
        assert path is not None
        pid = resident.stop(path)
        if pid is not None:
            wait_until(lambda: not alive(pid), "the resident ends on SIGTERM", 10.0)
        shutil.rmtree(folder, ignore_errors=True)


def _forget_front_end() -> None:
    """What the front end's exit does to its connection: closed (the resident stays)."""
    starter = warm_start._starter
    assert starter is not None
    starter.close()
    warm_start._starter = None


def test_motion_processes_fork_from_one_resident_that_outlives_its_front_end(
        agile: Profile, bus: EmulatorHandle, run_dir: str) -> None:
    client = MotionClient(agile, bus.port)
    starter = warm_start._starter
    assert starter is not None and starter.process is None  # not this front end's own
    first = starter.pid
    try:
        assert parent_pid(client.process.pid) == first
        assert os.getsid(client.process.pid) == client.process.pid
        assert len(client.ping_all()) == 3
    finally:
        client.close()
    assert client.process.poll() == 0  # the resident reports its fork's exit to its asker
    _forget_front_end()
    time.sleep(0.3)
    assert alive(first)  # it outlives the front end that started it
    client = MotionClient(agile, bus.port)  # "the next command"
    try:
        assert warm_start._starter is not None and warm_start._starter.pid == first
        assert parent_pid(client.process.pid) == first
        assert len(client.ping_all()) == 3
    finally:
        client.close()


def test_a_fork_takes_the_umask_and_cpus_of_its_front_end_of_the_moment(
        agile: Profile, bus: EmulatorHandle, run_dir: str) -> None:
    MotionClient(agile, bus.port).close()  # the resident starts under this umask (0o022)
    _forget_front_end()
    cpus = os.sched_getaffinity(0)
    old = os.umask(0o077)
    try:
        os.sched_setaffinity(0, {min(cpus)})
        client = MotionClient(agile, bus.port)
    finally:
        os.umask(old)
        os.sched_setaffinity(0, cpus)
    try:
        assert _umask_of(client.process.pid) == 0o077
        assert os.sched_getaffinity(client.process.pid) == {min(cpus)}
    finally:
        client.close()


def test_the_resident_ends_when_idle(agile: Profile, bus: EmulatorHandle, run_dir: str,
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(resident.ENV_IDLE, "1")
    MotionClient(agile, bus.port).close()
    assert warm_start._starter is not None
    pid = warm_start._starter.pid
    path = resident.socket_path()
    assert path is not None and os.path.exists(path)
    time.sleep(1.5)
    assert alive(pid)  # a connected front end keeps it
    _forget_front_end()
    wait_until(lambda: not alive(pid), "the idle resident ends", 10.0)
    assert not os.path.exists(path)


def test_sigterm_retires_it_but_its_running_motion_process_finishes(
        agile: Profile, bus: EmulatorHandle, run_dir: str) -> None:
    client = MotionClient(agile, bus.port)
    try:
        assert warm_start._starter is not None
        pid = warm_start._starter.pid
        for sig in (signal.SIGINT, signal.SIGHUP, signal.SIGQUIT):
            os.kill(pid, sig)
        time.sleep(0.3)
        assert alive(pid)
        path = resident.socket_path()
        assert path is not None
        os.kill(pid, signal.SIGTERM)
        wait_until(lambda: not os.path.exists(path), "the retired resident frees its path", 5.0)
        assert alive(pid) and len(client.ping_all()) == 3  # its motion process still serves
    finally:
        client.close()
    assert client.process.poll() == 0
    wait_until(lambda: not alive(pid), "the retired resident ends after its last fork", 10.0)


def _cli(cwd: Path, env: dict[str, str], *argv: str) -> dict[str, object]:
    done = subprocess.run([sys.executable, "-m", "spm_console", *argv, "--json"], cwd=cwd,
                          env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    reply = json.loads(done.stdout.splitlines()[-1])
    assert isinstance(reply, dict)
    return reply


def test_commands_share_it_until_its_code_changes_on_disk(tmp_path: Path, run_dir: str) -> None:
    """Two commands: one resident. An edit of a file it imported: the next command is told it
    is stale, it ends, and a fresh one serves. ``warm-start --stop`` ends that one."""
    copy = tmp_path / "install"
    shutil.copytree(ROOT / "spm_console", copy / "spm_console",
                    ignore=shutil.ignore_patterns("__pycache__"))
    env = dict(os.environ, PYTHONPATH=str(copy), XDG_RUNTIME_DIR=run_dir,
               SPM_CONSOLE_LOGS=str(tmp_path / "logs"))
    env.pop(warm_start.ENV_WARM_START, None)
    home = ("home", "--sim", "--plant", "ideal", "--profile", PROFILE)
    _cli(copy, env, *home)
    first = _cli(copy, env, "warm-start")
    assert first["mode"] == "resident" and isinstance(first["pid"], int)
    _cli(copy, env, *home)
    assert _cli(copy, env, "warm-start")["pid"] == first["pid"]
    edited = copy / "spm_console" / "motion" / "executor.py"
    edited.write_text(edited.read_text() + "\n# edited after the resident started\n")
    _cli(copy, env, *home)
    wait_until(lambda: not alive(int(first["pid"])), "the stale resident ends", 10.0)  # type: ignore[call-overload]
    second = _cli(copy, env, "warm-start")
    assert isinstance(second["pid"], int) and second["pid"] != first["pid"]
    stopped = _cli(copy, env, "warm-start", "--stop")
    assert stopped["stopped"] is True
    wait_until(lambda: not alive(int(second["pid"])), "the stopped resident ends", 10.0)  # type: ignore[call-overload]
    assert _cli(copy, env, "warm-start")["pid"] is None


def test_a_second_front_end_is_told_which_front_end_holds_the_bus(
        agile: Profile, bus: EmulatorHandle, run_dir: str) -> None:
    """The holder of the bus is a fork of the resident, whose parent is no front end (a
    command that has ended started it): the refusal names the front end that asked for it,
    as the resident noted."""
    path = resident.socket_path()
    assert path is not None
    code = ("import json, sys; sys.path[:] = json.loads(sys.argv[1]); "
            "from spm_console.system import resident; resident.spawn(sys.argv[2])")
    subprocess.run([sys.executable, "-c", code, json.dumps(sys.path), path], check=True,
                   timeout=30)
    wait_until(lambda: resident.running(path) is not None, "the resident listens", 10.0)
    first = MotionClient(agile, bus.port)
    assert warm_start._starter is not None
    assert parent_pid(warm_start._starter.pid) != os.getpid()
    try:
        assert len(first.ping_all()) == 3
        with pytest.raises(SpmError, match=f"in use by process {os.getpid()} "):
            MotionClient(agile, bus.port)
    finally:
        first.close()


def test_a_refused_request_starts_the_motion_process_directly(
        agile: Profile, bus: EmulatorHandle, run_dir: str) -> None:
    """A retired resident (SIGTERM, its motion process still running) refuses new forks
    before any touches the socket: the front end starts that motion process itself."""
    first = MotionClient(agile, bus.port)
    other = start_emulator(agile, record=False)
    try:
        assert warm_start._starter is not None
        os.kill(warm_start._starter.pid, signal.SIGTERM)
        path = resident.socket_path()
        assert path is not None
        wait_until(lambda: not os.path.exists(path), "the resident retires", 5.0)
        second = MotionClient(agile, other.port)
        try:
            assert isinstance(second.process, subprocess.Popen)  # started directly
            assert parent_pid(second.process.pid) == os.getpid()
            assert len(second.ping_all()) == 3
        finally:
            second.close()
    finally:
        first.close()
        other.stop()
