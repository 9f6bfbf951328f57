"""Live following on the emulated bus (issue 15): the servo loop re-plans every period
toward targets that change, checks every plan itself and streams only verified references."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

from spm_console.config.schema import Profile
from spm_console.core.planning.follow.timed import TimedTargets
from spm_console.devices.dynamixel.bus import open_bus
from spm_console.devices.emulator.bus import start_emulator
from spm_console.motion.follow.loop import Follower
from spm_console.motion.follow.regions import follow_regions
from spm_console.motion.follow.target_feed import TargetFeed
from spm_console.motion.logs.runlog import RunLog, load_run
from spm_console.motion.segments import ExecutionResult
from spm_console.system.simclock import SimClock
from tests.support.ws_helpers import agile_workspace


def _follow(profile: Profile, tmp_path: Path, start: np.ndarray, feed: TargetFeed
            ) -> tuple[ExecutionResult, Follower]:
    """Follow ``feed`` over a fresh in-process emulated bus powered on at ``start``, in
    simulated time."""
    clock = SimClock.create()
    emu = start_emulator(profile, record=False, initial_deg=list(start), sim=clock)
    bus = open_bus(profile, emu.port, sim=clock)
    try:
        log = RunLog.create("follow", profile.name, profile.digest(), [], root=tmp_path)
        ex = Follower(profile, bus, workspace=agile_workspace(), log=log, clock=clock.now,
                      sleep=clock.sleep)
        return ex.follow(feed), ex
    finally:
        bus.close()
        emu.stop()
        clock.close()


def test_timed_steps_are_followed_and_every_motion_is_certified(agile: Profile, tmp_path: Path) -> None:
    ws = agile_workspace()
    start = np.asarray(ws.theta_deg()[ws.home_index], float)
    steps = TimedTargets(np.array([0.0, 0.4, 1.2]),
                         np.vstack([start, start + np.array([6.0, -5.0, 4.0]), start + np.array([-4.0, 3.0, -2.0])]))
    res, ex = _follow(agile, tmp_path, start, TargetFeed(steps))
    assert res.ok, res.message
    np.testing.assert_allclose(res.final_deg, steps.theta_deg[-1], atol=0.3)
    st = ex.stats(TargetFeed(steps))
    assert st.adopted > 0.9 * st.solves and st.refused == 0 and st.clamped == 0
    # every sample carries the follower's own word on its target: never clamped here
    assert [s.target_clamp_deg for s in ex.samples if s.phase == "follow"] == \
        [0.0] * sum(s.phase == "follow" for s in ex.samples)
    meas = np.array([s.measured_deg for s in ex.samples if s.read_ok])  # (a lost read is NaN)
    assert ex.verifier.certified.contains(meas).all()
    run = load_run(res.log_dir)
    np.testing.assert_allclose(run.vec("target")[-1], steps.theta_deg[-1])
    assert any(e["event"] == "follow" for e in run.events)


def test_a_target_outside_the_region_is_projected_and_never_chased(agile: Profile, tmp_path: Path) -> None:
    ws = agile_workspace()
    start = np.asarray(ws.theta_deg()[ws.home_index], float)
    outside = np.array([160.0, 60.0, 160.0])  # far outside P
    assert not ws.region.contains(outside)
    feed = TargetFeed(TimedTargets(np.array([0.0, 0.2]), np.vstack([start, outside])))
    res, ex = _follow(agile, tmp_path, start, feed)
    assert res.ok, res.message
    st = ex.stats(feed)
    assert st.clamped > 0
    # … and the samples say how far the follower moved the target: well outside P here
    clamps = [s.target_clamp_deg for s in ex.samples if s.phase == "follow"]
    assert None not in clamps and max(c or 0.0 for c in clamps) > 1.0
    meas = np.array([s.measured_deg for s in ex.samples if s.read_ok])  # (a lost read is NaN)
    # the follower plans through the region cover and constrains the states its references
    # produce (not the references): the model under the references sent stays in one of
    # its regions, and the wrist settles on the nearest point of the region it ends in
    regions = follow_regions(ws, start).regions
    model = np.array([s.predicted_deg for s in ex.samples])
    worst = max(min(r.violation_deg(x) for r in regions) for x in model)
    assert worst < 0.05, worst
    assert ex.verifier.certified.contains(meas).all()
    assert min(r.violation_deg(res.final_deg) for r in regions) < 0.3
    assert not any(r.contains(outside) for r in regions)  # never reached: it was projected


def test_solves_that_miss_their_deadline_continue_the_previous_plan(
        agile: Profile, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    ws = agile_workspace()
    start = np.asarray(ws.theta_deg()[ws.home_index], float)
    feed = TargetFeed(TimedTargets(np.array([0.0, 0.1]), np.vstack([start, start + np.array([5.0, 5.0, -5.0])])))
    from spm_console.core.planning.follow import solver as follow_mod

    real = follow_mod.FollowSolver.solve
    calls = [0]

    def slow(self, *a, **k):  # type: ignore[no-untyped-def]
        calls[0] += 1
        out = real(self, *a, **k)
        if calls[0] % 3 == 0:  # every third re-plan "takes" 30 ms: past the budget
            from dataclasses import replace
            return replace(out, seconds=0.030)
        return out

    monkeypatch.setattr(follow_mod.FollowSolver, "solve", slow)
    res, ex = _follow(agile, tmp_path, start, feed)
    assert res.ok, res.message
    st = ex.stats(feed)
    assert st.misses >= st.solves // 3 - 1 and st.misses > 0
    np.testing.assert_allclose(res.final_deg, feed.final(start), atol=0.3)
    refs = np.array([s.reference_deg for s in ex.samples])
    assert np.abs(np.diff(refs, axis=0)).max() < 2.0  # smooth: misses continue the plan


def _session(agile: Profile, tmp_path: Path):  # type: ignore[no-untyped-def]
    from spm_console.services.session import Session

    s = Session(agile, sim=True, logs_root=tmp_path, emulator_process=True)
    s.connect()
    return s


@pytest.mark.slow  # a whole real-time run (the slow set runs in CI as its own stage)
def test_live_targets_deadman_and_the_change_to_reference_delay(agile: Profile, tmp_path: Path) -> None:
    """Through the runtime (the loop in the motion process): live targets sent from another
    thread; the deadman holds when they stop; ending the source settles and completes."""
    s = _session(agile, tmp_path)
    try:
        s.home()
        home = s.theta_deg.copy()
        new = home + np.array([4.0, -3.0, 2.0])
        out: list[object] = []
        following = threading.Event()  # the first sample: the loop runs (the deadman is armed)
        th = threading.Thread(target=lambda: out.append(
            s.following.follow(initial_deg=home, deadman_s=0.4, source="test",
                     on_sample=lambda _s: following.set())), daemon=True)
        th.start()
        assert following.wait(30)
        for _ in range(12):  # a live source: the same new target every 0.1 s for 1.2 s
            assert s.following.set_target(new)
            time.sleep(0.1)
        time.sleep(1.0)  # then silent for > 0.4 s: the deadman holds (where the wrist is)
        assert s.following.end_follow()
        th.join(20)
        fo = out[0]
    finally:
        s.close()
    ex = fo.execution  # type: ignore[attr-defined]
    assert ex.ok, ex.message
    run = load_run(ex.log_dir)
    k0 = int(next(e for e in run.events if e["event"] == "target")["k"])
    refs = run.vec("ref")
    moved = np.flatnonzero(np.abs(refs[k0:] - refs[k0]).max(axis=1) > 1e-6)
    assert moved.size and moved[0] <= 2  # the first changed reference within 2 periods
    assert [e["event"] for e in run.events].count("deadman") == 1
    np.testing.assert_allclose(ex.final_deg, new, atol=0.5)
    assert fo.stats.deadman_trips == 1  # type: ignore[attr-defined]


def test_estop_while_following(agile: Profile, tmp_path: Path) -> None:
    s = _session(agile, tmp_path)
    try:
        s.home()
        home = s.theta_deg.copy()
        out: list[object] = []
        th = threading.Thread(target=lambda: out.append(s.following.follow(initial_deg=home)), daemon=True)
        th.start()
        time.sleep(0.8)
        s.following.set_target(home + np.array([8.0, 8.0, -8.0]))
        time.sleep(0.3)
        assert s.estop("test stop")
        th.join(20)
    finally:
        s.close()
    ex = out[0].execution  # type: ignore[attr-defined]
    assert ex.outcome == "stopped" and int(ex.exit_code) == 20


def test_a_target_in_another_region_of_the_cover_is_reached_through_the_overlaps(
        agile: Profile, tmp_path: Path) -> None:
    """The target lies outside P, in a region of the cover only: the follower heads for the
    overlap with the next region, plans there once inside it, and reaches the target — every
    measured sample certified, the model's position always inside a region of the cover."""
    ws = agile_workspace()
    assert ws.cover is not None
    start = np.asarray(ws.theta_deg()[ws.home_index], float)
    far = next(np.asarray(ws.cover.seeds_deg[k]) for k in range(1, ws.cover.size)
               if not ws.region.contains(ws.cover.seeds_deg[k], tol=1e-6)
               and 0 not in ws.cover.containing(ws.cover.seeds_deg[k]))
    feed = TargetFeed(TimedTargets(np.array([0.0, 0.1]), np.vstack([start, far])))
    res, ex = _follow(agile, tmp_path, start, feed)
    assert res.ok, res.message
    np.testing.assert_allclose(res.final_deg, far, atol=0.3)
    st = ex.stats(feed)
    assert st.region_switches >= 1 and st.refused == 0 and st.clamped == 0
    meas = np.array([s.measured_deg for s in ex.samples if s.read_ok])
    assert ex.verifier.certified.contains(meas).all()
    run = load_run(res.log_dir)
    start_ev = next(e for e in run.events if e["event"] == "start")
    hops = [e for e in run.events if e["event"] == "region"]
    assert start_ev["regions"] == ws.cover.size and (hops or start_ev["region"] != 0)
    pred = np.array([s.predicted_deg for s in ex.samples])
    assert all(ws.cover.containing(p, tol=1e-3) for p in pred)  # the model in some region


#: A feasible node on the boundary of the Agile Wrist's certified set that no region of its
#: 2° cover holds (where a plan through a region grown around its goal leaves the wrist).
BOUNDARY_NODE = (87.0, 87.0, 153.0)


def test_following_starts_at_a_boundary_pose_outside_every_cover_region(
        agile: Profile, tmp_path: Path) -> None:
    """The follower grows a certified region around a start no cover region holds, joined to
    the cover by its overlaps, and follows from there: toward home through P, every measured
    sample certified."""
    ws = agile_workspace()
    assert ws.cover is not None
    start = np.asarray(BOUNDARY_NODE)
    assert not ws.cover.containing(start, tol=1e-3)  # the case: no cover region holds it
    home = np.asarray(ws.theta_deg()[ws.home_index], float)
    toward = start + 0.25 * (home - start)
    feed = TargetFeed(TimedTargets(np.array([0.0, 0.2]), np.vstack([start, toward])))
    res, ex = _follow(agile, tmp_path, start, feed)
    assert res.ok, res.message
    np.testing.assert_allclose(res.final_deg, toward, atol=0.3)
    meas = np.array([s.measured_deg for s in ex.samples if s.read_ok])
    assert ex.verifier.certified.contains(meas).all()
    start_ev = next(e for e in load_run(res.log_dir).events if e["event"] == "start")
    assert start_ev["grown_around_start"] == 1
    assert start_ev["regions"] == ws.cover.size + 1


def test_a_start_a_servo_tick_beyond_the_grid_says_where_and_what_to_do() -> None:
    """The paper's goal θ2 = 155° is the grid's edge; a wrist settled 0.04° beyond it has no
    certified region to follow in. The refusal says by how much and how to get back in."""
    from spm_console.errors import BadInputError
    from spm_console.motion.follow.regions import MOVE_IN

    ws = agile_workspace()
    hi = float(ws.axes_deg[1][-1])
    with pytest.raises(BadInputError) as info:
        follow_regions(ws, np.array([66.8, hi + 0.04, 131.48]))
    assert f"θ2 is 0.04° beyond the grid's {float(ws.axes_deg[1][0]):g}…{hi:g}°" in info.value.message
    assert info.value.message.endswith(MOVE_IN) and "home it first" not in info.value.message


def test_a_communication_loss_while_following_the_emulated_bus_names_its_causes(
        agile: Profile, tmp_path: Path) -> None:
    """Through the runtime's follow run (RunContext sim): the same reason as an execution on
    the emulated bus, not 'check the cable'."""
    from spm_console.devices.emulator.faults import FaultSpec
    from spm_console.errors import ExitCode
    from spm_console.motion.follow.run import run_follow
    from spm_console.motion.runs import RunContext

    ws = agile_workspace()
    start = np.asarray(ws.theta_deg()[ws.home_index], float)
    clock = SimClock.create()
    emu = start_emulator(agile, record=False, initial_deg=list(start), sim=clock)
    emu.inject(FaultSpec("unplug", 0.3))
    bus = open_bus(agile, emu.port, sim=clock)
    feed = TargetFeed(TimedTargets(np.array([0.0, 2.0]), np.vstack([start, start + 5.0])))
    try:
        out = run_follow(agile, bus, ws, feed, RunContext(port=emu.port, sim=True,
                                                          logs_root=str(tmp_path),
                                                          sim_clock=clock.path),
                         None, lambda ex: None, homed=True)
    finally:
        bus.close()
        emu.stop()
        clock.close()
    res = out.execution
    assert res.exit_code == ExitCode.STOP_COMM, res.message
    assert "on the emulated bus in simulated time, where no reply can be late: an injected fault" \
        in res.message
    assert "cable" not in res.message


def test_follow_start_moves_a_start_just_beyond_the_grid_one_tick_inside() -> None:
    from spm_console.motion.follow.regions import follow_start

    ws = agile_workspace()
    hi = float(ws.axes_deg[1][-1])
    inside = np.array([100.0, 120.0, 110.0])
    assert follow_start(ws, inside, 0.5, 0.088) is inside or np.array_equal(
        follow_start(ws, inside, 0.5, 0.088), inside)
    out = follow_start(ws, np.array([66.8, hi + 0.04, 131.48]), 0.5, 0.088)
    np.testing.assert_allclose(out, [66.8, hi - 0.088, 131.48])
    far = np.array([66.8, hi + 0.6, 131.48])  # beyond the approach tolerance: left as it is
    np.testing.assert_array_equal(follow_start(ws, far, 0.5, 0.088), far)


def test_following_starts_from_a_wrist_settled_a_tick_beyond_the_grid(
        agile: Profile, tmp_path: Path) -> None:
    """The paper's goal θ2 = 155° is the grid's edge, where a plan's end settles a servo tick
    beyond it. The follower moves the wrist into the region first (to its point nearest the
    wrist two ticks deep, every cycle under the region check), then plans: the run
    succeeds (no region stop) and logs where it started planning."""
    ws = agile_workspace()
    hi = float(ws.axes_deg[1][-1])
    start = np.array([66.8, hi + 0.04, 131.48])
    toward = np.array([70.0, 150.0, 128.0])
    feed = TargetFeed(TimedTargets(np.array([0.0, 0.2]), np.vstack([start, toward])))
    res, ex = _follow(agile, tmp_path, start, feed)
    assert res.ok, res.message
    np.testing.assert_allclose(res.final_deg, toward, atol=0.3)
    events = load_run(res.log_dir).events
    start_ev = next(e for e in events if e["event"] == "start")
    begin = np.asarray(start_ev["start_deg"])  # inside the grid, within the approach tolerance
    assert begin[1] < hi - 360 / 4096 and np.abs(begin - start).max() <= agile.safety.approach_tolerance_deg
    assert any(e["event"] == "approached" for e in events)
    st = ex.stats(feed)
    assert st.approach_cycles < 25 and st.adopted > 0
