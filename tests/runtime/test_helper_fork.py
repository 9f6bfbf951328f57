"""The emulated bus's process forked by the front end's warm start (services.zygote_forks):
it serves as the one started with ``python -m`` does, ends with its session, and ends when
the front end that asked for it is killed (its parent is the warm start, not the front end)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from spm_console.config.schema import Profile
from spm_console.devices.emulator.child import EmulatorChild
from spm_console.services import warm_start
from spm_console.services.session import Session
from tests.support.procfs import alive, parent_pid
from tests.support.terminal_helpers import wait_until


@pytest.fixture
def own_warm_start(monkeypatch: pytest.MonkeyPatch) -> None:
    """A warm start of this test's own (none shared with an earlier test)."""
    monkeypatch.setenv(warm_start.ENV_WARM_START, warm_start.PER_COMMAND)
    for name, value in (("_starter", None), ("_pending", None), ("_spawned", None),
                        ("_starter_failed", "")):
        monkeypatch.setattr(warm_start, name, value)


def test_the_consoles_emulated_bus_is_a_fork_of_its_warm_start(agile: Profile,
                                                               own_warm_start: None) -> None:
    session = Session(agile, sim=True, emulator_process=True)
    try:
        session.connect()
        child = session.emulator
        assert isinstance(child, EmulatorChild) and child.forked
        pid = child.pid
        assert pid is not None and warm_start._starter is not None
        assert parent_pid(pid) == warm_start._starter.pid  # not this process: its warm start
        ids = sorted(j.id for j in agile.bus.joints)
        assert sorted(s.id for s in session.bus_state.statuses) == ids  # it serves
        theta = session.read_position()
        assert theta is not None and len(theta) == 3
    finally:
        session.disconnect()
        if warm_start._starter is not None:
            warm_start._starter.close()
    wait_until(lambda: not alive(pid), "the forked bus ends with its session", 10.0)


def test_a_killed_front_end_takes_its_forked_bus_with_it(tmp_path: Path) -> None:
    """SIGKILL to a front end (no clean-up runs in it): the bus its warm start forked sees
    its pidfd of the front end end, and leaves."""
    script = textwrap.dedent(f"""
        import sys, time
        from pathlib import Path
        from spm_console.config.load import load_profile
        from spm_console.services.session import Session
        s = Session(load_profile(Path({str(Path('profiles/agile_wrist.toml').resolve())!r})),
                    sim=True, emulator_process=True)
        s.connect()
        print(s.emulator.pid, int(s.emulator.forked), flush=True)
        time.sleep(120)
    """)
    env = {**os.environ, warm_start.ENV_WARM_START: warm_start.PER_COMMAND}
    front = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True,
                             env=env, start_new_session=True)
    try:
        assert front.stdout is not None
        line = front.stdout.readline().split()
        assert len(line) == 2, line
        pid, forked = int(line[0]), line[1] == "1"
        assert forked and alive(pid) and parent_pid(pid) != front.pid
        front.send_signal(signal.SIGKILL)
        front.wait(10)
        wait_until(lambda: not alive(pid), "the forked bus ends with its front end", 10.0)
    finally:
        if front.poll() is None:
            os.killpg(front.pid, signal.SIGKILL)
            front.wait(10)


def test_a_request_for_any_other_module_is_refused_before_a_fork() -> None:
    from spm_console.services.zygote_forks import Request

    base = {"id": 1, "env": {}, "cwd": "/", "parent": os.getpid()}
    assert Request.parse(json.dumps(
        {**base, "helper": "spm_console.devices.emulator.child"}).encode()).parent == os.getpid()
    for bad in ({**base, "helper": "os"}, {**base, "helper": "spm_console.devices.emulator.child",
                                             "parent": 0}):
        with pytest.raises(ValueError, match="no helper"):
            Request.parse(json.dumps(bad).encode())
