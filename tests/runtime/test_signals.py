"""Every terminating signal stops the wrist and closes the log (SPEC §8, §9).

``execute`` runs as a subprocess, as an operator runs it: SIGINT, SIGTERM, SIGHUP and
SIGQUIT mid-motion each end in the E-stop (exit 20, hold written, log ``stopped``);
SIGKILL cannot be caught, so the log must hold every cycle but the last few, and the
run is then listed as ``killed``. The SIGKILL run talks to an emulator in this
process, so what the killed process did survives it.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.config.schema import Profile
from spm_console.devices.emulator.bus import start_emulator
from spm_console.errors import ExitCode
from spm_console.motion.logs.runlog import FLUSH_EVERY, list_runs, load_run
from spm_console.motion.plans import synthetic_plan
from spm_console.services.oneshot import RunRequest, execute_once
from spm_console.store.plan_file import save_plan
from spm_console.system.signals import STOP_SIGNALS, stop_signals
from tests.support.exec_helpers import PAPER_START
from tests.support.terminal_helpers import last_measured

GOAL = np.array([100.0, 120.0, 110.0])
# paced: the signals land while the wrist moves; its kill tests drive an emulated bus on the
# wall clock (see tests/conftest.py)
pytestmark = [pytest.mark.usefixtures("sighup_default", "paced_clock"), pytest.mark.realtime]


def test_one_handler_for_every_stop_signal_then_the_old_ones_back() -> None:
    before = {s: signal.getsignal(s) for s in STOP_SIGNALS}
    seen: list[signal.Signals] = []
    with stop_signals(seen.append):
        assert all(signal.getsignal(s) not in (before[s], signal.SIG_DFL) for s in STOP_SIGNALS)
        for s in STOP_SIGNALS:
            os.kill(os.getpid(), s)
            time.sleep(0.01)  # delivered to the main thread at its next bytecode
    assert seen == list(STOP_SIGNALS)
    assert {s: signal.getsignal(s) for s in STOP_SIGNALS} == before


def test_an_ignored_sighup_stays_ignored_under_nohup() -> None:
    old = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        with stop_signals(lambda _s: None):
            assert signal.getsignal(signal.SIGHUP) == signal.SIG_IGN
            assert signal.getsignal(signal.SIGTERM) not in (signal.SIG_DFL, signal.SIG_IGN)
        assert signal.getsignal(signal.SIGHUP) == signal.SIG_IGN
    finally:
        signal.signal(signal.SIGHUP, old)


@pytest.fixture(scope="module")
def long_plan(tmp_path_factory: pytest.TempPathFactory, agile: Profile) -> Path:
    path = tmp_path_factory.mktemp("plans") / "long.json"
    save_plan(synthetic_plan(agile, PAPER_START, GOAL, 4.0), path)  # 4 s of motion
    return path


def _spawn(args: list[str], logs: Path) -> subprocess.Popen[str]:
    env = {**os.environ, "SPM_CONSOLE_LOGS": str(logs)}
    return subprocess.Popen([sys.executable, "-m", "spm_console", *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _rows(run_dir: Path) -> int:
    """Complete data rows flushed so far."""
    text = (run_dir / "samples.csv").read_text()
    return max(0, text.count("\n") - 1)


def _wait_for_rows(logs: Path, rows: int, proc: subprocess.Popen[str], timeout: float = 30.0) -> Path:
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end and proc.poll() is None:
        runs = [p for p in logs.glob("*") if (p / "samples.csv").is_file()]
        if runs and _rows(runs[0]) >= rows:
            return runs[0]
        time.sleep(0.02)
    raise AssertionError(f"the run did not log {rows} rows (exit {proc.poll()})")


@pytest.mark.parametrize("sig", STOP_SIGNALS, ids=lambda s: s.name)
def test_each_signal_mid_motion_is_an_estop(tmp_path: Path, long_plan: Path,
                                            sig: signal.Signals) -> None:
    proc = _spawn(["execute", "--plan", str(long_plan), "--sim", "--json", "--skip-homing",
                   "signal test", "--sim-start", *map(str, PAPER_START)], tmp_path / "logs")
    run_dir = _wait_for_rows(tmp_path / "logs", 25, proc)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=20)
    assert proc.returncode == int(ExitCode.STOP_ESTOP), err
    d = json.loads(out)
    assert d["outcome"] == "stopped" and d["message"] == f"E-stop: signal {sig.name}"
    run = load_run(run_dir)
    assert run.meta["outcome"] == "stopped" and run.meta["exit_code"] == int(ExitCode.STOP_ESTOP)
    assert run.rows == d["stats"]["samples"] < 150 and not run.truncated  # all rows, closed
    stop = next(e for e in run.events if e["event"] == "stop")
    assert stop["kind"] == "estop" and stop["action"] == "hold" and stop["notes"] == []
    # the hold is the last measured position, short of the goal
    # the last good reading (a lost last reply logs NaN); 6 digits in the log
    np.testing.assert_allclose(stop["hold_deg"], last_measured(run.vec("meas")), atol=1e-3)
    assert np.abs(np.asarray(stop["hold_deg"]) - GOAL).max() > 5.0
    assert [r.meta["outcome"] for r in list_runs(tmp_path / "logs")] == ["stopped"]


def test_a_signal_before_the_motion_interrupts_with_nothing_moved(
        tmp_path: Path, agile: Profile) -> None:
    """The signal lands once the bus is open, before homing: no torque, log ``interrupted``,
    130."""
    plan = synthetic_plan(agile, PAPER_START, GOAL, 1.5)
    before = signal.getsignal(signal.SIGHUP)

    def hangup(_session: object) -> None:
        assert signal.getsignal(signal.SIGHUP) not in (before, signal.SIG_DFL)  # ours is in place
        os.kill(os.getpid(), signal.SIGHUP)

    req = RunRequest(sim=True, log_root=tmp_path, on_connected=hangup)
    with pytest.raises(Exception, match="interrupted by SIGHUP before any motion") as exc:
        execute_once(agile, plan, req)
    assert getattr(exc.value, "exit_code", None) == ExitCode.INTERRUPTED
    assert signal.getsignal(signal.SIGHUP) is before  # the previous handler is back
    run = load_run("last", tmp_path)
    assert run.meta["outcome"] == "interrupted" and run.meta["exit_code"] == 130
    assert run.rows == 0 and "torque_on" not in [e["event"] for e in run.events]


def test_a_signal_whose_interrupt_a_library_lost_refuses_the_run(
        tmp_path: Path, agile: Profile) -> None:
    """A signal before the run's own handling, whose interrupt a library caught (the CLI's
    start-up record keeps it): the run is refused as interrupted, nothing moves, 130."""
    plan = synthetic_plan(agile, PAPER_START, GOAL, 1.5)
    req = RunRequest(sim=True, log_root=tmp_path, lost_signal=lambda: signal.SIGQUIT)
    with pytest.raises(Exception, match="interrupted by SIGQUIT before any motion") as exc:
        execute_once(agile, plan, req)
    assert getattr(exc.value, "exit_code", None) == ExitCode.INTERRUPTED
    run = load_run("last", tmp_path)
    assert run.meta["outcome"] == "interrupted" and run.meta["exit_code"] == 130
    assert run.rows == 0 and "torque_on" not in [e["event"] for e in run.events]


def test_sigkill_of_the_loop_loses_at_most_three_cycles_and_the_run_is_listed_killed(
        tmp_path: Path, long_plan: Path, agile: Profile) -> None:
    """SIGKILL of the motion process (the loop and the log's writer): the CLI reports it (27),
    the servos' Bus Watchdog stops them, the log keeps all but the last few cycles."""
    em = start_emulator(agile, record=False, initial_deg=PAPER_START)
    goals: list[int] = []  # every goal written to joint 1: one per cycle, after one at torque-on
    servo = em.servos[0]
    apply = servo._apply

    def spy(name: str, value: int) -> None:
        if name == "goal_position":
            goals.append(value)
        apply(name, value)

    servo._apply = spy  # type: ignore[method-assign]
    try:
        proc = _spawn(["execute", "--plan", str(long_plan), "--port", em.port, "--skip-homing",
                       "signal test"], tmp_path / "logs")
        run_dir = _wait_for_rows(tmp_path / "logs", 40, proc)
        meta = list_runs(tmp_path / "logs")[0].meta
        assert meta["outcome"] == "running"  # alive: running
        loop_pid = int(meta["process"]["pid"])
        assert loop_pid != proc.pid  # the loop runs in its own process
        time.sleep(0.047)  # kill between two flushes (every 3 cycles = 60 ms)
        os.kill(loop_pid, signal.SIGKILL)
        _out, err = proc.communicate(timeout=20)
        assert proc.returncode == int(ExitCode.MOTION_PROCESS_LOST), err
        assert "motion process is gone" in err and "Traceback" not in err
        with em._lock:  # the emulator has served its last request
            cycles = len(goals) - 1  # cycles the killed process had begun
        time.sleep(agile.safety.watchdog_ms / 1000 + 0.2)
        a = em.joint_deg()
        time.sleep(0.1)
        assert np.abs(em.joint_deg() - a).max() < 0.01  # the watchdog stopped the servos
    finally:
        em.stop()
    run = load_run(run_dir)
    lost = cycles - run.rows
    print(f"SIGKILL after {cycles} cycles: {run.rows} rows in the log, {lost} lost "
          f"(flush every {FLUSH_EVERY})")
    assert 0 <= lost <= 3, (cycles, run.rows)
    assert np.array_equal(run.columns["k"], np.arange(run.rows))  # complete rows, no holes
    assert np.isfinite(run.vec("meas")).all(axis=1).mean() > 0.9  # (a lost reply is a NaN row)
    assert np.isfinite(run.vec("vel")).all()
    # the lifecycle in order (a retried read, legitimate on a loaded machine, may interleave)
    lifecycle = [e["event"] for e in run.events if e["event"] != "comm_retry"]
    assert lifecycle[:5] == ["plan_verified", "start", "realtime", "watchdog", "torque_on"]
    [listed] = list_runs(tmp_path / "logs")
    assert listed.meta["outcome"] == "killed" and run.meta["outcome"] == "killed"
    assert f"process {loop_pid}" in listed.meta["message"]
    assert json.loads((run_dir / "meta.json").read_text())["outcome"] == "running"  # file as left
    assert main(["logs", "--logs", str(tmp_path / "logs")]) == 0


def test_sigkill_of_the_cli_makes_the_loop_hold_and_log_client_lost(
        tmp_path: Path, long_plan: Path, agile: Profile) -> None:
    em = start_emulator(agile, record=False, initial_deg=PAPER_START)
    try:
        proc = _spawn(["execute", "--plan", str(long_plan), "--port", em.port, "--skip-homing",
                       "signal test"], tmp_path / "logs")
        _wait_for_rows(tmp_path / "logs", 25, proc)
        proc.kill()  # the client: no goodbye, its end of the socket closes
        proc.communicate(timeout=20)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and list_runs(tmp_path / "logs")[0].meta["outcome"] == "running":
            time.sleep(0.05)
        run = load_run(list_runs(tmp_path / "logs")[0].path)
        assert run.meta["outcome"] == "stopped" and "client lost" in run.meta["message"]
        stop = next(e for e in run.events if e["event"] == "stop")
        assert stop["action"] == "hold" and stop["done_t"] - stop["detected_t"] <= 2 * agile.servo.ts_s
        # holding: once the servos have reached the hold goal (eq. (27) settles within
        # 10/p ≈ 0.3 s), they stay there
        time.sleep(10.0 / agile.servo.p)
        a = em.joint_deg()
        time.sleep(0.5)
        assert np.abs(em.joint_deg() - a).max() < 0.01
    finally:
        em.stop()


def test_a_signal_after_the_motion_ended_is_told_and_the_result_stands(
        tmp_path: Path, agile: Profile, monkeypatch: pytest.MonkeyPatch) -> None:
    """SIGTERM once the execution has returned, before the session closes: nothing moves, so
    nothing is stopped; the run stays completed and the front end is told (the probe saw such
    a signal swallowed without a word)."""
    from spm_console.services.session import Session

    real = Session.execute

    def execute_then_signal(self: Session, *a: object, **kw: object):  # type: ignore[no-untyped-def]
        res = real(self, *a, **kw)  # type: ignore[arg-type]
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.05)  # the handler runs in this (main) thread at its next bytecode
        return res

    monkeypatch.setattr(Session, "execute", execute_then_signal)
    told: list[str] = []
    plan = synthetic_plan(agile, PAPER_START, GOAL, 2.0)
    req = RunRequest(sim=True, log_root=tmp_path, sim_start_deg=PAPER_START,
                     skip_homing="signal test", on_late_signal=told.append)
    out = execute_once(agile, plan, req)
    assert out.execution.ok and out.execution.exit_code == ExitCode.OK
    assert told == ["SIGTERM"]
    assert load_run("last", tmp_path).meta["outcome"] == "completed"
