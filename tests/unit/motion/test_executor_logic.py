"""Executor logic against an in-test fake bus on a simulated clock (deterministic timing; the
pty emulator in real time runs in test_executor_emulated and test_faults_exec): deadlines,
every stop kind, refusals, homing."""

from __future__ import annotations

import errno
import threading
from pathlib import Path

import numpy as np
import pytest

from spm_console.config.schema import Profile
from spm_console.core.polytope.region import Region
from spm_console.errors import BadInputError, ExitCode, PlanRefusedError, RunLogError, UnreachableError
from spm_console.motion.executor import Executor, Segment
from spm_console.motion.homing import check_assembly_mode, home
from spm_console.motion.logs.runlog import RunLog, load_run
from spm_console.motion.plans import line_plan, synthetic_plan
from tests.support.fake_bus import FakeBus, SimClock
from tests.support.ws_helpers import agile_workspace

START = np.array([120.0, 100.0, 110.0])
GOAL = np.array([140.0, 125.0, 95.0])


def _sim(start: np.ndarray) -> FakeBus:
    return FakeBus(start, clock=SimClock())


def _executor(profile: Profile, bus: FakeBus, tmp_path: Path, **kw) -> Executor:  # type: ignore[no-untyped-def]
    log = RunLog.create("execute", profile.name, profile.digest(), [], root=tmp_path)
    clock = {} if bus.clock is None else {"clock": bus.clock, "sleep": bus.clock.sleep}
    return Executor(profile, bus, workspace=agile_workspace(), log=log, on_start=bus.start_clock, **clock, **kw)


def _run(profile: Profile, bus: FakeBus, plan, tmp_path: Path, **kw):  # type: ignore[no-untyped-def]
    ex = _executor(profile, bus, tmp_path, **kw)
    return ex, ex.run([Segment("plan", plan)])


def _stop_event(path: Path) -> dict:  # type: ignore[type-arg]
    run = load_run(path)
    stops = [e for e in run.events if e["event"] == "stop"]
    assert len(stops) == 1, run.events
    return stops[0]


def _with_safety(profile: Profile, **upd: object) -> Profile:
    return profile.model_copy(update={"safety": profile.safety.model_copy(update=upd)})


def test_completes_with_drift_free_deadlines(agile: Profile, tmp_path: Path) -> None:
    plan = synthetic_plan(agile, START, GOAL, 1.0)
    bus = _sim(START)
    seen: list[int] = []

    def on_sample(sample) -> None:  # type: ignore[no-untyped-def]
        seen.append(sample.k)
        if sample.k == 10:
            bus.clock.sleep(0.05)  # type: ignore[union-attr]  # a 50 ms hiccup (2.5 periods)

    ex = _executor(agile, bus, tmp_path, on_sample=on_sample)
    res = ex.run([Segment("plan", plan)])
    assert res.ok and res.exit_code == ExitCode.OK, res.message
    assert seen == list(range(plan.N + 1))
    ts = agile.servo.ts_s
    late = np.array([s.t for s in ex.samples]) - np.arange(len(ex.samples)) * ts
    # absolute deadlines: on time before the hiccup, the two cycles it covered run late,
    # then every cycle starts exactly on its own deadline again: nothing accumulates
    assert np.allclose(late[:11], 0.0, atol=1e-9)
    assert (late[11:13] > 0.005).all()
    assert np.allclose(late[13:], 0.0, atol=1e-9)
    assert res.stats.late_ms.max > 30.0 and res.stats.overruns == 1
    assert res.final_deg is not None and np.allclose(res.final_deg, GOAL, atol=0.2)
    assert res.stats.tracking_rms_deg < 0.3
    run = load_run(res.log_dir)  # type: ignore[arg-type]
    assert run.rows == plan.N + 1 and run.meta["outcome"] == "completed"
    assert bus.writes[0][1].tolist() == pytest.approx(START.tolist(), abs=0.1)  # reseeded goal
    assert bus.torque_calls[0][1] is True


def test_estop_from_the_telemetry_callback(agile: Profile, tmp_path: Path) -> None:
    plan = synthetic_plan(agile, START, GOAL, 1.5)
    bus = _sim(START)
    holder: list[Executor] = []

    def on_sample(sample) -> None:  # type: ignore[no-untyped-def]
        if sample.k == 25:
            holder[0].request_estop("button")

    ex = _executor(agile, bus, tmp_path, on_sample=on_sample)
    holder.append(ex)
    res = ex.run([Segment("plan", plan)])
    assert res.exit_code == ExitCode.STOP_ESTOP and "button" in res.message
    assert len(ex.samples) == 26  # no further cycle
    stop = _stop_event(res.log_dir)  # type: ignore[arg-type]
    ts = agile.servo.ts_s
    assert 25 * ts < stop["detected_t"] < 26 * ts  # at once, not at the next deadline
    assert stop["issued_t"] - stop["detected_t"] < 1e-9
    assert stop["done_t"] - stop["detected_t"] <= ts + 1e-9
    hold = np.array(stop["hold_deg"])
    assert np.allclose(bus.writes[-1][1], hold) and np.allclose(bus.writes[-2][1], hold)
    assert np.allclose(hold, ex.samples[-1].measured_deg, atol=1e-9)


@pytest.mark.realtime  # how soon the loop wakes on the wall clock
def test_estop_from_another_thread(agile: Profile, tmp_path: Path) -> None:
    plan = synthetic_plan(agile, START, GOAL, 1.5)
    bus = FakeBus(START)  # real time: the request comes from another thread
    ex = _executor(agile, bus, tmp_path)
    timer = threading.Timer(0.5, ex.request_estop, args=("test button",))
    timer.start()
    res = ex.run([Segment("plan", plan)])
    timer.join()
    assert res.exit_code == ExitCode.STOP_ESTOP and "test button" in res.message
    stop = _stop_event(res.log_dir)  # type: ignore[arg-type]
    # woken at once by the request (not at the next deadline, nor at the plan's end, 1.5 s
    # and more); when the request comes is the timer thread's scheduling, not the loop's
    assert 0.0 <= stop["detected_t"] - stop["requested_t"] < 0.5 * agile.servo.ts_s
    assert stop["detected_t"] < 1.0
    assert len(ex.samples) < plan.N


def test_single_failures_are_retried_then_n_in_a_row_stop(agile: Profile, tmp_path: Path) -> None:
    plan = synthetic_plan(agile, START, GOAL, 1.0)
    bus = _sim(START)
    bus.fail_read_calls = {5, 9, 10, 20}  # isolated losses: retried, counted
    bus.fail_reads_after = 0.6
    _ex, res = _run(agile, bus, plan, tmp_path)
    assert res.exit_code == ExitCode.STOP_COMM
    assert "3 consecutive" in res.message
    assert res.stats.comm_retries == 4 + 2 * 3
    assert res.stats.comm_failed_cycles == 4  # the cycle with reads 9+10, then 3 at the end
    stop = _stop_event(res.log_dir)  # type: ignore[arg-type]
    ts = agile.servo.ts_s
    assert stop["detected_t"] == pytest.approx(0.6 + 2 * ts, abs=ts / 2)
    assert stop["issued_t"] - stop["detected_t"] <= 2 * 0.004 + 0.001  # the cycle's 2 timeouts
    assert stop["done_t"] - stop["detected_t"] <= ts + 1e-9


def test_stall_stops_on_tracking_error(agile: Profile, tmp_path: Path) -> None:
    plan = synthetic_plan(agile, START, GOAL, 1.0)
    bus = _sim(START)
    bus.stall_joint, bus.stall_after = 1, 0.3
    ex, res = _run(agile, bus, plan, tmp_path)
    assert res.exit_code == ExitCode.STOP_TRACKING and "joint 2" in res.message
    assert ex.samples[-1].tracking_error_deg > agile.safety.tracking_error_deg
    assert ex.samples[-2].tracking_error_deg <= agile.safety.tracking_error_deg


@pytest.mark.parametrize("alerts", [False, True])
def test_hardware_error_stops(agile: Profile, tmp_path: Path, alerts: bool) -> None:
    bus = _sim(START)
    bus.hw_error_after = 0.2
    bus.expose_alerts = alerts
    ex, res = _run(agile, bus, synthetic_plan(agile, START, GOAL, 1.0), tmp_path)
    assert res.exit_code == ExitCode.STOP_HW_ERROR
    assert "joint 2" in res.message and "overload" in res.message
    # with the status packets' alert flag: the next cycle; without: the periodic poll (25 cycles)
    assert len(ex.samples) == (11 if alerts else 26)


def test_region_exit_stops(agile: Profile, tmp_path: Path) -> None:
    # an external push of joint 1 by 36°: from ~121° to ~157°, outside the grid (65..155°)
    # but inside the servo limits (160°): the certified set, not the plan's region, stops it
    plan = synthetic_plan(agile, START, GOAL, 1.0)
    tight = Region(np.array([[1.0, 0.0, 0.0]]), np.array([130.0]))  # what the file claims: ignored
    plan = type(plan)(**{**plan.__dict__, "region": tight})
    bus = _sim(START)
    bus.push_after, bus.push_deg = 0.1, 36.0
    ex, res = _run(agile, bus, plan, tmp_path)
    assert res.exit_code == ExitCode.STOP_REGION, res.message
    assert "certified feasible set" in res.message
    assert ex.samples[-1].measured_deg[0] > 155.0
    assert all(s.measured_deg[0] < 140.0 for s in ex.samples[:-1])


def test_servo_limit_stops_and_hold_is_within_limits(agile: Profile, tmp_path: Path) -> None:
    start = np.array([150.0, 100.0, 110.0])
    bus = _sim(start)
    bus.push_after, bus.push_deg = 0.2, 12.0  # an external push beyond the 160° limit
    plan = synthetic_plan(agile, start, start, 0.6)
    _ex, res = _run(agile, bus, plan, tmp_path)
    assert res.exit_code == ExitCode.STOP_LIMIT and "joint 1" in res.message
    assert bus.writes[-1][1][0] == agile.bus.joints[0].max_deg  # held at the limit, logged


def test_torque_off_stop_action(agile: Profile, tmp_path: Path) -> None:
    prof = _with_safety(agile, stop_action="torque_off")
    bus = _sim(START)
    bus.stall_joint, bus.stall_after = 0, 0.2
    _ex, res = _run(prof, bus, synthetic_plan(prof, START, GOAL, 1.0), tmp_path)
    assert res.exit_code == ExitCode.STOP_TRACKING
    assert bus.torque_calls[-1][1] is False
    assert _stop_event(res.log_dir)["action"] == "torque_off"  # type: ignore[arg-type]


def test_refusals_move_nothing(agile: Profile, tmp_path: Path) -> None:
    bus = _sim(START)
    bad = synthetic_plan(agile, START, np.array([165.0, 100.0, 100.0]), 1.0)
    with pytest.raises(PlanRefusedError, match="servo limits"):
        Executor(agile, bus, workspace=agile_workspace()).run([Segment("plan", bad)])
    far = synthetic_plan(agile, START + 5.0, GOAL, 1.0)
    with pytest.raises(BadInputError, match="plan starts at"):
        Executor(agile, bus, workspace=agile_workspace()).run([Segment("plan", far)])
    assert bus.writes == [] and bus.torque_calls == []


def test_homing_line_is_speed_bounded_and_reaches_home(agile: Profile, tmp_path: Path) -> None:
    start = np.array([110.0, 150.0, 125.0])
    plan = line_plan(agile, start, np.array(agile.home.theta_deg), agile.safety.home_speed_degps)
    assert np.abs(plan.velocity_degps).max() <= agile.safety.home_speed_degps - 1.0
    bus = _sim(start)
    r = home(_executor(agile, bus, tmp_path))
    assert r.execution.ok, r.execution.message
    assert np.allclose(r.execution.final_deg, agile.home.theta_deg, atol=0.1)  # type: ignore[arg-type]
    assert r.pose is not None and np.allclose(r.pose.n, [0, 0, 1], atol=2e-3)
    assert r.execution.stats.samples == plan.N + 1


def test_homing_refuses_outside_the_known_assembly_mode(agile: Profile) -> None:
    with pytest.raises(UnreachableError, match="known assembly mode: crosses a type-2"):
        check_assembly_mode(agile, np.array([40.0, 150.0, 150.0]))
    assert check_assembly_mode(agile, np.array([110.0, 150.0, 125.0])).zeta > 0.1


def test_an_estop_before_the_motion_switches_nothing_on(agile: Profile, tmp_path: Path) -> None:
    bus = _sim(START)
    ex = _executor(agile, bus, tmp_path)
    ex.request_estop("signal SIGTERM", by_signal=True)
    res = ex.run([Segment("plan", synthetic_plan(agile, START, GOAL, 1.0))])
    # nothing moved: an interruption (130), as a signal before any motion always is
    assert res.exit_code == ExitCode.INTERRUPTED and "before any motion" in res.message
    assert "nothing moved" in res.message and not res.ok
    assert bus.torque_calls == [] and bus.writes == [] and res.stats.samples == 0
    assert load_run(res.log_dir).meta["outcome"] == "interrupted"


def test_an_estop_between_torque_on_and_the_first_reference_holds_and_is_an_interruption(
        agile: Profile, tmp_path: Path) -> None:
    """The signal lands just after torque-on, before cycle 0: the wrist holds where it stood
    (the stop action is applied and logged) and, with no reference sent, the run is an
    interruption (130), not a stopped motion (20)."""
    bus = _sim(START)
    ex = _executor(agile, bus, tmp_path)
    set_torque = bus.set_torque

    def torque_then_signal(on: bool) -> None:
        set_torque(on)
        if on:
            ex.request_estop("signal SIGQUIT", by_signal=True)

    bus.set_torque = torque_then_signal  # type: ignore[method-assign]
    res = ex.run([Segment("plan", synthetic_plan(agile, START, GOAL, 1.0))])
    assert res.exit_code == ExitCode.INTERRUPTED and res.stats.samples == 0
    assert "signal SIGQUIT" in res.message and "nothing moved" in res.message
    run = load_run(res.log_dir)  # type: ignore[arg-type]
    assert run.meta["outcome"] == "interrupted" and run.meta["exit_code"] == 130
    stop = next(e for e in run.events if e["event"] == "stop")
    assert stop["action"] == "hold"
    np.testing.assert_allclose(stop["hold_deg"], START, atol=0.1)  # held where it stood


def test_an_operator_estop_before_the_first_reference_is_a_stop_not_an_interruption(
        agile: Profile, tmp_path: Path) -> None:
    """The E-stop button (not a signal) pressed before the first cycle: a stop (20), the log
    ``stopped``: only a terminating signal makes a run with nothing moved an interruption."""
    bus = _sim(START)
    ex = _executor(agile, bus, tmp_path)
    ex.request_estop("operator E-stop (SPACE)")
    res = ex.run([Segment("plan", synthetic_plan(agile, START, GOAL, 1.0))])
    assert res.exit_code == ExitCode.STOP_ESTOP and "before any motion" in res.message
    assert load_run(res.log_dir).meta["outcome"] == "stopped"  # type: ignore[arg-type]


class _FullDisk:
    """A CSV writer whose rows stop fitting after ``rows`` (ENOSPC, as a full disk gives)."""

    def __init__(self, inner, rows: int) -> None:  # type: ignore[no-untyped-def]
        self.inner, self.left = inner, rows

    def writerow(self, row: list[str]) -> None:
        if self.left <= 0:
            raise OSError(errno.ENOSPC, "No space left on device")
        self.left -= 1
        self.inner.writerow(row)


def test_a_run_whose_log_cannot_be_written_stops_holding_and_closes_its_log(
        agile: Profile, tmp_path: Path) -> None:
    """The disk fills at sample 30: the run stops at once (exit 20, the wrist holding at its
    last reading), and meta.json says why; the rows after the failure are not written."""
    plan = synthetic_plan(agile, START, GOAL, 1.5)
    bus = _sim(START)
    ex = _executor(agile, bus, tmp_path)
    assert ex.log is not None
    ex.log._csv = _FullDisk(ex.log._csv, 30)  # type: ignore[assignment]
    with pytest.raises(RunLogError) as info:
        ex.run([Segment("plan", plan)])
    assert info.value.exit_code == ExitCode.STOP_ESTOP
    assert len(ex.samples) == 31 < plan.N  # the row that failed was the 31st
    hold = ex.samples[-1].measured_deg
    assert np.allclose(bus.writes[-1][1], hold, atol=1e-9)  # the hold, after the last reference
    run = load_run(ex.log.path)
    assert run.rows == 30
    assert run.meta["outcome"] == "error" and run.meta["exit_code"] == int(ExitCode.STOP_ESTOP)
    assert run.meta["log_write_error"] == "No space left on device"
    assert "cannot be written" in run.meta["message"]


class _SaggingBus(FakeBus):
    """Joint 2 rests ``sag_deg`` short of its goal (the links' weight on a P-only drive)."""

    sag_deg = 0.2

    def _advance(self) -> None:
        goal = self.goal
        self.goal = goal - np.array([0.0, self.sag_deg, 0.0])
        try:
            super()._advance()
        finally:
            self.goal = goal


def test_settling_at_a_goal_on_the_grids_face_sends_the_shift_the_monitor_allows(
        agile: Profile, tmp_path: Path) -> None:
    """The paper's goal lies on the workspace grid's 155° face (θ2). A joint 2 resting short of
    it is shifted past the face, within the band where the safety monitor lets the measured
    position be (the region margin), and settles on the goal, which is in the set."""
    from spm_console.report.paper_values import MVN_GOAL_DEG

    goal = np.array(MVN_GOAL_DEG)
    assert goal[1] == 155.0
    start = goal - np.array([0.0, 3.0, 0.0])
    settling = agile.model_copy(update={"settle": agile.settle.model_copy(
        update={"duration_s": 1.5, "tolerance_deg": 0.1})})
    bus = _SaggingBus(start, clock=SimClock())
    ex, res = _run(settling, bus, synthetic_plan(settling, start, goal, 0.6), tmp_path)
    assert res.ok, res.message
    assert res.settle is not None and res.settle.settled, res.settle
    assert res.settle.refused_shifts == 0
    assert abs(res.settle.error_deg[1]) <= 0.1
    sent = max(w[1][1] for w in bus.writes)
    assert 155.0 < sent <= 155.0 + settling.settle.max_correction_deg
    assert all(s.measured_deg[1] <= 155.0 + 0.1 for s in ex.samples)


def test_a_shifted_goal_keeps_the_tolerance_and_a_tick_from_where_the_monitor_stops(
        agile: Profile, tmp_path: Path) -> None:
    """A sag larger than the band past the face (1.5° here, shifts allowed up to 2°): the goals
    sent stop short of the band's edge by the tolerance and a tick, so a joint that slips onto
    its shifted goal is no region stop; the run completes, unsettled, holding."""
    from spm_console.config.models import servo_tick_deg
    from spm_console.report.paper_values import MVN_GOAL_DEG

    goal = np.array(MVN_GOAL_DEG)
    start = goal - np.array([0.0, 3.0, 0.0])
    law = agile.settle.model_copy(update={"duration_s": 1.0, "tolerance_deg": 0.1,
                                          "max_correction_deg": 2.0})
    settling = agile.model_copy(update={"settle": law})
    bus = _SaggingBus(start, clock=SimClock())
    bus.sag_deg = 1.5
    ex, res = _run(settling, bus, synthetic_plan(settling, start, goal, 0.6), tmp_path)
    assert res.ok, res.message
    assert res.settle is not None and not res.settle.settled and res.settle.refused_shifts > 0
    assert ex.safety is not None
    edge = ex.safety.region_half_width_deg + law.tolerance_deg + servo_tick_deg(settling)
    sent = np.array([w[1] for w in bus.writes])
    assert sent[:, 1].max() > 155.0  # shifted past the face, into the band
    assert ex.verifier.certified.contains(sent, edge).all()
