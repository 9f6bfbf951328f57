"""The servo loop in its own process: a client drives it over the pipe; E-stop by message;
a client killed mid-motion makes the loop hold ("client lost"); a killed loop process leaves
the servos to their Bus Watchdog and the client reports it (exit 27). Emulated bus on a pty."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from spm_console.config.schema import Profile
from spm_console.devices.emulator.bus import start_emulator
from spm_console.errors import BadInputError, ExitCode, MotionProcessLostError
from spm_console.motion.logs.runlog import list_runs, load_run
from spm_console.motion.plans import synthetic_plan
from spm_console.motion.protocol import ESTOP_SIGNAL, EStop, Planned
from spm_console.motion.sample import Sample
from spm_console.motion.server import DEADMAN_S
from spm_console.services.client import MotionClient
from spm_console.store.plan_file import save_plan
from tests.support.exec_helpers import PAPER_START

pytestmark = pytest.mark.realtime  # an emulated bus on the wall clock (see tests/conftest.py)

GOAL = np.array([100.0, 120.0, 110.0])


def _stop(run_dir: Path) -> dict:  # type: ignore[type-arg]
    stops = [e for e in load_run(run_dir).events if e["event"] == "stop"]
    assert len(stops) == 1
    return stops[0]  # type: ignore[no-any-return]


def _still(emu: object, wait_s: float = 0.3) -> None:
    """The wrist holds: the joints do not move any more."""
    time.sleep(wait_s)
    a = emu.joint_deg()  # type: ignore[attr-defined]
    time.sleep(0.1)
    b = emu.joint_deg()  # type: ignore[attr-defined]
    assert np.abs(b - a).max() < 0.01, (a, b)


@pytest.fixture
def cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return Path(os.environ.get("SPM_CONSOLE_CACHE") or tmp_path_factory.mktemp("cache"))


def test_drive_the_loop_process_and_estop_by_message(agile: Profile, tmp_path: Path,
                                                     cache: Path) -> None:
    emu = start_emulator(agile, record=False, initial_deg=list(PAPER_START))
    client = MotionClient(agile, emu.port, cache_dir=cache, logs_root=tmp_path)
    try:
        assert client.pid != os.getpid()
        assert [s.model_number for s in client.ping_all()] == [321, 321, 321]
        assert np.allclose(client.read_position(), PAPER_START, atol=0.1)
        plan = synthetic_plan(agile, PAPER_START, GOAL, 1.5)
        # the runtime's rule: homed first, or an explicit override (logged)
        with pytest.raises(BadInputError, match="not homed"):
            client.execute(plan)
        refused = load_run("last", tmp_path)
        assert refused.meta["outcome"] == "refused" and refused.rows == 0
        got: list[int] = []
        told: list[tuple[Planned, int]] = []  # what the runtime said it runs, samples seen then
        client.on_planned = lambda p: told.append((p, len(got)))
        away = synthetic_plan(agile, PAPER_START + np.array([2.0, -2.0, 1.0]), GOAL, 1.5)
        res = client.execute(away, lambda s: got.append(s.k), skip_homing="test")
        assert res.ok, res.message
        assert got == list(range(res.stats.samples))  # every sample reached the client
        # before the first sample, the runtime said what it would run: its approach, the plan
        (planned, seen), = told
        assert seen == 0 and planned.phases == ("approach", "plan")
        assert planned.duration_s == pytest.approx(res.stats.samples * agile.servo.ts_s)
        assert planned.duration_s > (away.N + 1) * away.Ts  # the approach counted once, there
        # a long motion, stopped by a message
        timer = threading.Timer(0.8, lambda: client.estop("test E-stop"))
        timer.start()
        res = client.execute(synthetic_plan(agile, GOAL, PAPER_START, 4.0), skip_homing="test")
        assert res.exit_code == ExitCode.STOP_ESTOP and "test E-stop" in res.message
        stop = _stop(res.log_dir)
        ts = agile.servo.ts_s
        assert stop["detected_t"] - stop["requested_t"] <= ts  # reached the loop within a period
        assert stop["done_t"] - stop["detected_t"] <= 2 * ts  # hold written within 2 periods
        _still(emu)
    finally:
        client.close()
        emu.stop()
    assert client.process.poll() is not None  # the loop process ended with the client's close


def test_an_estop_late_for_its_motion_stops_nothing_and_one_between_motions_stops_the_next(
        agile: Profile, tmp_path: Path, cache: Path) -> None:
    """An E-stop sent as a motion ends (its result on the way) that reaches the motion process
    after it ended was that motion's: the next motion runs. One sent between motions, once the
    result was in, stops the next motion before it moves."""
    emu = start_emulator(agile, record=False, initial_deg=list(PAPER_START))
    client = MotionClient(agile, emu.port, cache_dir=cache, logs_root=tmp_path)
    try:
        away = PAPER_START + np.array([1.0, -1.0, 0.5])
        there = synthetic_plan(agile, PAPER_START, away, 0.3)
        before = client._ended_motion
        assert client.execute(there, skip_homing="test").ok
        client._send(EStop("SPACE as the run ended", None, False, before))  # it came late
        back = synthetic_plan(agile, away, PAPER_START, 0.3)
        res = client.execute(back, skip_homing="test")
        assert res.ok, res.message
        client.estop("SPACE between two runs")
        res = client.execute(there, skip_homing="test")
        assert res.exit_code == ExitCode.STOP_ESTOP
        assert "SPACE between two runs (before any motion)" in res.message
        assert client.execute(there, skip_homing="test").ok  # it stopped that one only
    finally:
        client.close()
        emu.stop()


def test_the_estop_signal_stops_the_motion_under_way(agile: Profile, tmp_path: Path,
                                                     cache: Path) -> None:
    """The client's second path when its connection is gone (ESTOP_SIGNAL to the motion
    process): an E-stop of the motion under way (20, not an interruption), the wrist holding."""
    emu = start_emulator(agile, record=False, initial_deg=list(PAPER_START))
    client = MotionClient(agile, emu.port, cache_dir=cache, logs_root=tmp_path)
    try:
        def on_sample(s: Sample) -> None:
            if s.k == 20:  # the wrist moves
                os.kill(client.pid, ESTOP_SIGNAL)

        res = client.execute(synthetic_plan(agile, PAPER_START, GOAL, 4.0), on_sample,
                             skip_homing="test")
        assert res.exit_code == ExitCode.STOP_ESTOP
        assert "E-stop signal to the motion process" in res.message
        assert _stop(res.log_dir)["action"] == "hold"
        _still(emu)
    finally:
        client.close()
        emu.stop()


CLIENT = textwrap.dedent("""
    import sys, numpy as np
    from spm_console.config.load import load_profile
    from spm_console.services.client import MotionClient
    from spm_console.store.plan_file import load_plan
    prof = load_profile("profiles/agile_wrist.toml")
    c = MotionClient(prof, sys.argv[1], cache_dir=sys.argv[3], logs_root=sys.argv[4])
    print(c.process.pid, flush=True)
    seen = []
    def on_sample(s):
        if len(seen) == 0:
            print("moving", flush=True)
        seen.append(s.k)
    c.execute(load_plan(sys.argv[2], prof), on_sample, skip_homing="test")
""")


def test_a_client_killed_mid_motion_makes_the_loop_hold(agile: Profile, tmp_path: Path,
                                                        cache: Path) -> None:
    plan = tmp_path / "long.json"
    save_plan(synthetic_plan(agile, PAPER_START, GOAL, 4.0), plan)
    emu = start_emulator(agile, record=False, initial_deg=list(PAPER_START))
    logs = tmp_path / "logs"
    proc = subprocess.Popen([sys.executable, "-c", CLIENT, emu.port, str(plan), str(cache), str(logs)],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        loop_pid = int(proc.stdout.readline())
        assert proc.stdout.readline().strip() == "moving"
        time.sleep(0.3)
        proc.kill()  # SIGKILL: no goodbye, the pipe just closes
        proc.wait(10)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            runs = list_runs(logs)
            if runs and runs[0].meta["outcome"] != "running":
                break
            time.sleep(0.05)
        run = list_runs(logs)[0]
        assert run.meta["outcome"] == "stopped" and run.meta["exit_code"] == int(ExitCode.STOP_ESTOP)
        assert "client lost" in run.meta["message"]
        stop = _stop(run.path)
        assert stop["done_t"] - stop["detected_t"] <= 2 * agile.servo.ts_s
        assert load_run(run.path).rows < 150  # long before the plan's end
        _still(emu)
        for _ in range(100):  # and the loop process does not outlive its client
            try:
                os.kill(loop_pid, 0)
            except ProcessLookupError:
                break
            time.sleep(0.05)
        else:
            pytest.fail("the motion process outlived its client")
    finally:
        if proc.poll() is None:
            proc.kill()
        emu.stop()


def test_a_killed_loop_process_leaves_the_servos_to_their_watchdog(
        agile: Profile, tmp_path: Path, cache: Path) -> None:
    emu = start_emulator(agile, record=False, initial_deg=list(PAPER_START))
    client = MotionClient(agile, emu.port, cache_dir=cache, logs_root=tmp_path)
    out: dict[str, object] = {}
    started = threading.Event()

    def run() -> None:
        try:
            client.execute(synthetic_plan(agile, PAPER_START, GOAL, 4.0),
                           lambda s: started.set(), skip_homing="test")
        except MotionProcessLostError as exc:
            out["error"] = exc

    t = threading.Thread(target=run)
    t.start()
    try:
        assert started.wait(20)
        time.sleep(0.3)
        os.kill(client.pid, signal.SIGKILL)
        t.join(10)
        err = out.get("error")
        assert isinstance(err, MotionProcessLostError) and err.exit_code == ExitCode.MOTION_PROCESS_LOST
        assert "Bus Watchdog" in err.message
        # the Bus Watchdog (profile: 100 ms) stops the servos on their own
        _still(emu, wait_s=agile.safety.watchdog_ms / 1000 + 0.3)
        assert abs(emu.joint_deg() - GOAL).max() > 1.0  # stopped short of the goal
    finally:
        client.close()
        emu.stop()


def test_deadman_is_several_heartbeats() -> None:
    from spm_console.motion.server import HEARTBEAT_S

    assert DEADMAN_S >= 3 * HEARTBEAT_S


def test_one_run_log_schema_for_every_front_end(agile: Profile, tmp_path: Path, cache: Path) -> None:
    """The CLI's one-shot run and a client of the motion process write the same metadata."""
    from spm_console.services.oneshot import RunRequest, execute_once

    plan = synthetic_plan(agile, PAPER_START, GOAL, 1.5)
    execute_once(agile, plan, RunRequest(sim=True, log_root=tmp_path / "cli", cache_dir=cache,
                                         handle_signals=False, skip_homing="schema test",
                                         sim_start_deg=PAPER_START))
    emu = start_emulator(agile, record=False, initial_deg=list(PAPER_START))
    client = MotionClient(agile, emu.port, cache_dir=cache, logs_root=tmp_path / "mp", sim=True)
    try:
        client.execute(plan, skip_homing="schema test")
    finally:
        client.close()
        emu.stop()
    a = load_run(list_runs(tmp_path / "cli")[0].path).meta
    b = load_run(list_runs(tmp_path / "mp")[0].path).meta
    assert set(a) == set(b)
    for key in ("bus", "sim", "faults", "process", "homing"):
        assert key in a
    assert a["bus"] == b["bus"] == "emulated bus" and a["sim"] is b["sim"] is True


def test_telemetry_never_blocks_the_loop_and_counts_what_a_slow_client_missed() -> None:
    """The loop's side only appends; a client that does not read blocks the sender thread."""
    from spm_console.motion.protocol import Telemetry
    from spm_console.motion.sample import Sample
    from spm_console.motion.serving.telemetry import MAX_PENDING, TELEMETRY_CHUNK, TelemetryOut

    release = threading.Event()
    sent: list[Telemetry] = []

    def stuck_send(msg: object) -> None:  # a client that does not read: the socket is full
        release.wait(10)
        assert isinstance(msg, Telemetry)
        sent.append(msg)

    out = TelemetryOut(stuck_send)
    sample = Sample.__new__(Sample)  # contents do not matter here
    loop = threading.Thread(target=lambda: [out.put(sample) for _ in range(3 * MAX_PENDING)])
    loop.start()
    loop.join(5.0)
    assert not loop.is_alive()  # every put returned while the sender was still stuck
    release.set()
    out.close()
    delivered = sum(len(m.samples) for m in sent)
    dropped = sum(m.dropped for m in sent)
    assert delivered + dropped == 3 * MAX_PENDING and dropped > 0
    # a backlog goes out in small messages: pickling one holds the GIL the loop needs
    assert max(len(m.samples) for m in sent) <= TELEMETRY_CHUNK
