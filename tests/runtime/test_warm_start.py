"""The warm start of the motion process (spm_console.services.warm_start / .zygote), per front
end (the suite's default; the resident one is tests/runtime/test_resident.py): each
motion process is a fork of one warm process per front end, in a session of its own, with
the front end's environment of the moment; the direct start stays available."""

from __future__ import annotations

import os
import signal
import subprocess
import time

import pytest

from spm_console.config.schema import Profile
from spm_console.devices.emulator.bus import EmulatorHandle
from spm_console.services import warm_start
from spm_console.services.client import MotionClient
from tests.support.procfs import parent_pid
from tests.support.terminal_helpers import wait_until


def test_motion_processes_are_forks_of_one_warm_start_each_in_a_session_of_its_own(
        agile: Profile, bus: EmulatorHandle) -> None:
    pids, parents = [], set()
    for _ in range(2):
        client = MotionClient(agile, bus.port)
        try:
            pid = client.process.pid
            pids.append(pid)
            parents.add(parent_pid(pid))
            assert os.getsid(pid) == pid  # signals to our group or terminal never reach it
            assert len(client.ping_all()) == 3
        finally:
            client.close()
        assert client.process.poll() == 0  # ended with the client's close, and said how
    starter = warm_start._starter
    assert starter is not None and parents == {starter.process.pid} and pids[0] != pids[1]
    assert os.getsid(starter.process.pid) == starter.process.pid


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="CPU placement needs 2 CPUs")
def test_a_fork_gets_the_environment_of_the_moment_it_was_asked_for(
        agile: Profile, bus: EmulatorHandle, monkeypatch: pytest.MonkeyPatch) -> None:
    """The warm start was started long before; the CPU placement asked for now (read by the
    motion process from its environment) is the one the fork follows."""
    first = MotionClient(agile, bus.port)
    first.close()
    cpu = min(os.sched_getaffinity(0))
    monkeypatch.setenv("SPM_CONSOLE_LOOP_CPU", str(cpu))
    client = MotionClient(agile, bus.port)
    try:
        assert os.sched_getaffinity(client.process.pid) == {cpu}
    finally:
        client.close()


def test_the_direct_start_stays_available(agile: Profile, bus: EmulatorHandle,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(warm_start.ENV_WARM_START, "0")
    client = MotionClient(agile, bus.port)
    try:
        assert isinstance(client.process, subprocess.Popen)
        assert parent_pid(client.process.pid) == os.getpid()
        assert os.getsid(client.process.pid) == client.process.pid
        assert len(client.ping_all()) == 3
    finally:
        client.close()


def test_the_warm_start_ignores_terminating_signals_and_ends_with_its_owner() -> None:
    starter = warm_start.WarmStart.own()
    starter.await_ready()  # it ignores them from then on
    pid = starter.process.pid
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT):
        os.kill(pid, sig)
    time.sleep(0.3)
    assert starter.process.poll() is None
    starter.close()  # the owner closes its socket (as it does by exiting)
    assert starter.process.poll() is not None


def test_a_dead_warm_start_is_replaced(agile: Profile, bus: EmulatorHandle) -> None:
    MotionClient(agile, bus.port).close()
    old = warm_start._starter
    assert old is not None
    old.process.kill()
    old.process.wait(5)
    wait_until(lambda: not old.alive, 5.0)
    client = MotionClient(agile, bus.port)
    try:
        assert len(client.ping_all()) == 3
        new = warm_start._starter
        assert new is not None and new is not old and parent_pid(client.process.pid) == new.process.pid
    finally:
        client.close()
