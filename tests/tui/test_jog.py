"""The live jog (issue 15, from step 5): the arrow keys move a target the wrist follows live,
through the runtime's following; esc ends it (the run completes), SPACE stops it."""

from __future__ import annotations

import asyncio
import re
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from textual.pilot import Pilot
from textual.widgets import DataTable

from spm_console.motion.logs.runlog import load_run
from spm_console.tui.app import SpmConsoleApp
from spm_console.tui.screens.execute import ExecuteScreen
from spm_console.tui.screens.help import HelpScreen
from spm_console.tui.screens.jog import JOG_SOURCE, JogScreen
from spm_console.tui.screens.jog_target import JOG_STEPS_DEG, JogTarget, TargetSender
from spm_console.viewer.view import NullView
from tests.support.console_helpers import settle, status_of, text_of

SIZE = (130, 42)
#: The emulated wrist settles on its target within this, deg (the follower's own settle
#: tolerance is 0.2°, plus the emulated encoder's resolution).
SETTLED_DEG = 0.5


async def until(pilot: Pilot[Any], cond: Callable[[], bool], what: str,
                timeout_s: float = 30.0) -> None:
    """Pump the app until ``cond()`` holds (a running following never lets the workers
    settle)."""
    loop = asyncio.get_running_loop()
    t_end = loop.time() + timeout_s
    while not cond():
        if loop.time() > t_end:
            raise TimeoutError(f"waited in vain for {what}")
        await pilot.pause(0.02)


async def _homed_on_step5(app: SpmConsoleApp, pilot: Pilot[Any]) -> None:
    await settle(pilot)
    await asyncio.to_thread(app.session.home)
    assert app.session.homed
    await pilot.press("5")
    await settle(pilot)


async def _start_jog(app: SpmConsoleApp, pilot: Pilot[Any]) -> JogScreen:
    await pilot.press("j")
    await until(pilot, lambda: isinstance(app.screen, JogScreen), "the jog screen")
    jog = app.screen
    assert isinstance(jog, JogScreen)
    await until(pilot, lambda: jog.phase == "live", "the first cycle of the following")
    assert app.moving
    return jog


async def _ended(app: SpmConsoleApp, pilot: Pilot[Any]) -> None:
    await until(pilot, lambda: isinstance(app.screen, ExecuteScreen) and not app.moving,
                "the end of the jog")
    await settle(pilot)


class ViewSpy(NullView):
    """A 3D view that remembers what it was asked to show."""

    def __init__(self) -> None:
        self.measured: list[Any] = []
        self.ghosts: list[Any] = []

    def show_theta(self, theta_deg: Any) -> None:
        self.measured.append(None if theta_deg is None else np.asarray(theta_deg, float))

    def show_target(self, theta_deg: Any) -> None:
        self.ghosts.append(None if theta_deg is None else np.asarray(theta_deg, float))


def _spy_targets(app: SpmConsoleApp) -> list[np.ndarray]:
    """Record every target the console hands to the runtime."""
    sent: list[np.ndarray] = []
    real = app.session.following.set_target

    def spy(theta_deg: Any) -> bool:
        sent.append(np.asarray(theta_deg, float).copy())
        return real(theta_deg)

    app.session.following.set_target = spy  # type: ignore[method-assign]
    return sent


async def test_joint_jog_moves_the_target_and_ending_settles_there(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _homed_on_step5(app, pilot)
        sent = _spy_targets(app)
        view = app.view = ViewSpy()
        home = np.asarray(app.session.profile.home.theta_deg, float)
        jog = await _start_jog(app, pilot)
        assert jog.target is not None and jog.target.mode == "rpy"
        await pilot.press("m")  # per joint
        assert jog.target.mode == "joint" and "per joint" in text_of(app, "#jog-mode")
        step = jog.target.step_deg
        await pilot.press("right", "right", "up", "pagedown")
        want = home + np.array([2 * step, step, -step])
        np.testing.assert_allclose(jog.target.theta_deg, want)
        await until(pilot, lambda: len(sent) == 4, "four targets sent")
        np.testing.assert_allclose(sent[0], home + np.array([step, 0, 0]))  # one per key, at once
        np.testing.assert_allclose(sent[-1], want)
        np.testing.assert_allclose(view.ghosts[-1], want)  # the target: the ghost
        assert len(view.measured) > 0  # the measured pose: solid, from the telemetry
        assert "inside P: not clamped" in text_of(app, "#jog-target")
        await until(pilot, lambda: jog.last_sample is not None
                    and jog.last_sample.target_deg is not None
                    and np.allclose(jog.last_sample.target_deg, want), "the loop's target")
        await pilot.press("escape")  # end: the wrist settles on the last target
        await _ended(app, pilot)
        res = app.session.last_run
        assert res is not None and res.ok and int(res.exit_code) == 0, res.message
        np.testing.assert_allclose(res.final_deg, want, atol=SETTLED_DEG)
        assert view.ghosts[-1] is None  # no ghost once the jog ended
        out = text_of(app, "#exec-outcome")
        assert out.startswith("COMPLETED (exit code 0)") and "live jog: " in out
        assert "live jog completed" in status_of(app)
        # the clock and loop-timing lines are the jog's, not an earlier plan's
        assert text_of(app, "#exec-clock").startswith("live jog: ")
        assert f"{res.stats.samples} cycles" in text_of(app, "#exec-timing")
        run = load_run(res.log_dir)
        np.testing.assert_allclose(run.vec("target")[-1], want)  # the log's target column
        np.testing.assert_allclose(run.vec("target")[0], home)
        assert run.info.kind == "follow" and run.meta["plans"][0]["source"] == JOG_SOURCE
        await pilot.press("6")  # the run is listed in the logs
        await settle(pilot)
        rows = app.screen.query_one("#runs", DataTable)
        kinds = [str(rows.get_row_at(i)[1]) for i in range(rows.row_count)]
        assert "follow" in kinds


async def test_a_target_pushed_out_of_p_is_clamped_live_and_not_wound_up(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _homed_on_step5(app, pilot)
        sent = _spy_targets(app)
        jog = await _start_jog(app, pilot)
        assert jog.target is not None
        await pilot.press("m", "plus", "plus")  # per joint, 5° steps
        for _ in range(40):  # θ1 up until P's edge refuses the next step
            await pilot.press("right")
            if "already" in status_of(app):
                break
        assert status_of(app).startswith("the target is already")
        assert "CLAMPED" in text_of(app, "#jog-target")
        last = jog.target.theta_deg.copy()
        await until(pilot, lambda: "CLAMPED" in text_of(app, "#jog-clamp"),
                    "the loop's target shown clamped (from the telemetry)")
        np.testing.assert_allclose(sent[-1], last)  # the refused step sent nothing
        await pilot.press("escape")
        await _ended(app, pilot)
        res = app.session.last_run
        assert res is not None and res.ok, res.message
        ws = app.session.wrist.workspace
        assert float(ws.region.violation_deg(res.final_deg)) < SETTLED_DEG  # P's nearest point
        assert float(np.abs(res.final_deg - last).max()) > SETTLED_DEG  # not the target
        m = re.search(r"(\d+) periods with the target clamped", text_of(app, "#exec-outcome"))
        assert m is not None and int(m.group(1)) > 0


async def test_rpy_jog_uses_ik_from_home_and_the_step_keys(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _homed_on_step5(app, pilot)
        s = app.session
        jog = await _start_jog(app, pilot)
        assert jog.target is not None
        np.testing.assert_allclose(jog.target.rpy_deg, [0, 0, 0], atol=1e-9)  # from home
        for _ in JOG_STEPS_DEG:
            await pilot.press("plus")
        assert jog.target.step_deg == JOG_STEPS_DEG[-1]  # the largest, and stays there
        assert f"step {JOG_STEPS_DEG[-1]:g}°" in text_of(app, "#jog-mode")
        await pilot.press("minus", "minus")
        big = JOG_STEPS_DEG[-3]
        assert jog.target.step_deg == big
        await pilot.press("right", "up", "pageup")  # yaw +, pitch +, roll +
        want_rpy = np.array([big, big, big])
        np.testing.assert_allclose(jog.target.rpy_deg, want_rpy)
        want = s.wrist.ik(want_rpy)
        np.testing.assert_allclose(jog.target.theta_deg, want)
        await pilot.press("m", "m")  # per joint and back: the same orientation
        assert jog.target.mode == "rpy"
        np.testing.assert_allclose(jog.target.rpy_deg, want_rpy, atol=1e-6)
        await pilot.press("j")  # the same key ends it
        await _ended(app, pilot)
        res = s.last_run
        assert res is not None and res.ok, res.message
        np.testing.assert_allclose(res.final_deg, want, atol=SETTLED_DEG)


async def test_jog_is_refused_before_homing_and_while_moving(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        assert app.session.bus is not None and not app.session.homed
        await pilot.press("5")
        await settle(pilot)
        await pilot.press("j")
        await pilot.pause()
        assert isinstance(app.screen, ExecuteScreen)
        assert "the wrist is not homed: press 1, then h" in status_of(app)
        assert app.session.last_run is None  # nothing moved
        await asyncio.to_thread(app.session.home)
        app.moving = True  # another motion under way
        await pilot.press("j")
        await pilot.pause()
        assert isinstance(app.screen, ExecuteScreen) and "busy" in status_of(app)
        app.moving = False


async def test_esc_while_the_workspace_loads_closes_the_jog_and_nothing_moves(console) -> None:
    import threading

    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _homed_on_step5(app, pilot)
        s = app.session
        runs_before = s.last_run
        gate = threading.Event()
        real = s.wrist.ensure_workspace

        def slow() -> Any:
            gate.wait(30)
            return real()

        s.wrist.ensure_workspace = slow  # type: ignore[method-assign]
        await pilot.press("j")
        await until(pilot, lambda: isinstance(app.screen, JogScreen), "the jog screen")
        assert app.moving  # the steps are locked from the start
        await pilot.press("right")
        assert "workspace is loading" in status_of(app)
        await pilot.press("escape")
        await until(pilot, lambda: isinstance(app.screen, ExecuteScreen), "the execute step")
        assert not app.moving and "nothing moved" in status_of(app)
        gate.set()
        await settle(pilot)
        assert s.last_run is runs_before and isinstance(app.screen, ExecuteScreen)


async def test_estop_during_jog_stops_with_exit_20(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _homed_on_step5(app, pilot)
        jog = await _start_jog(app, pilot)
        await pilot.press("m", "plus", "plus", "right", "right", "up")
        await pilot.press("space")
        await _ended(app, pilot)
        res = app.session.last_run
        assert res is not None and res.outcome == "stopped" and int(res.exit_code) == 20
        assert text_of(app, "#exec-outcome").startswith("STOPPED (exit code 20)")
        assert "STOPPED" in status_of(app)
        assert jog.phase == "done"
        # a jog has no planned length: no progress bar (a stopped one read "0%")
        assert not app.screen.query_one("#exec-progress").display


async def test_the_arrows_win_over_the_help_key_list_and_it_names_the_jog(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _homed_on_step5(app, pilot)
        from spm_console.tui.screens.help import help_table, key_entries

        descs = [e.description for _n, es in key_entries(app.screen, app) for e in es]
        assert "Live jog" in descs
        assert any("Live jog" in c.title for c in app.get_system_commands(app.screen))  # palette
        jog = await _start_jog(app, pilot)
        entries = {e.description: e.keys_text for _n, es in key_entries(jog, app) for e in es}
        assert entries["Yaw or θ1 −/+"] == "← →" and entries["End jog"] == "esc j"
        from rich.console import Console

        con = Console(width=120, record=True)
        con.print(help_table(jog, app))
        assert "Live jog (from step 5)" in con.export_text()
        await pilot.press("question_mark")
        assert isinstance(app.screen, HelpScreen)
        await pilot.press("escape")  # closes the help, not the jog
        assert app.screen is jog and jog.phase == "live"
        assert jog.target is not None
        before = jog.target.rpy_deg.copy()
        await pilot.press("left")
        assert jog.target.rpy_deg[2] == pytest.approx(before[2] - jog.target.step_deg)
        await pilot.press("question_mark")  # the help open when the jog ends
        await pilot.press("space")
        await _ended(app, pilot)
        assert int(app.session.last_run.exit_code) == 20


def test_a_target_outside_is_sent_once_and_not_wound_up() -> None:
    outside = lambda th: max(0.0, float(th[0]) - 10.0)  # noqa: E731  P: θ1 ≤ 10°
    t = JogTarget(np.array([9.0, 0.0, 0.0]), None, lambda r: r, outside)
    assert t.mode == "joint"  # no orientation known: per joint only
    assert t.nudge(0, 1) == "" and t.outside_deg == pytest.approx(0.0)
    assert t.nudge(0, 1) == "" and t.outside_deg == pytest.approx(1.0)  # out once: clamped
    why = t.nudge(0, 1)
    assert why.startswith("the target is already 1.00° outside every region")
    assert t.theta_deg[0] == pytest.approx(11.0)
    assert t.nudge(1, 1) == ""  # along the edge: allowed
    assert t.nudge(0, -1) == "" and t.outside_deg == pytest.approx(0.0)  # back in
    assert t.toggle_mode(lambda th: None).startswith("θ = ")  # no orientation: stays
    assert t.mode == "joint"


def test_the_sender_keeps_the_order_and_ends_after_the_last_target() -> None:
    got: list[Any] = []
    sender = TargetSender(lambda th: got.append(tuple(th)) or True,
                          lambda: got.append("end") or True)
    for i in range(5):
        sender.put(np.array([i, 0.0, 0.0]))
    sender.end()
    sender.put(np.array([9.0, 0.0, 0.0]))  # after the end: not taken
    sender.close()
    assert got == [(float(i), 0.0, 0.0) for i in range(5)] + ["end"]
    assert sender.sent == 5 and sender.error is None


def _settled_deg(session: Any, timeout_s: float = 2.0) -> Any:
    """The wrist's position once three reads in a row agree (the servos reach their last
    goal's tick after a run's last cycle; how far they got by then depends on the host)."""
    import time

    reads = [session.read_position()]
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        time.sleep(0.03)
        reads.append(session.read_position())
        if len(reads) >= 3 and all(np.array_equal(r, reads[-1]) for r in reads[-3:]):
            break
    return reads[-1]


async def _jog_after_a_plan_to(app: Any, pilot: Any, goal: Any) -> tuple[Any, Any]:
    """Home, plan (MVN) to ``goal`` (deg), execute it, wait for the wrist to settle, then start
    a jog on step 5: (the jog screen, the settled joint angles, deg)."""
    from spm_console.services.wrist_service import PoseSpec

    await settle(pilot)
    s = app.session
    await asyncio.to_thread(s.home)
    s.wrist.ensure_workspace()
    await asyncio.to_thread(s.plans.solve, "mvn", PoseSpec("current"), PoseSpec("theta", goal), s.theta_deg, 150)
    done = await asyncio.to_thread(s.execute, s.plans.plan)
    assert done.ok, done.message
    settled = await asyncio.to_thread(_settled_deg, s)
    await pilot.press("5")
    await settle(pilot)
    jog = await _start_jog(app, pilot)
    assert jog.target is not None
    return jog, settled


async def _end_completed(app: Any, pilot: Any) -> Any:
    """End the jog with esc: it completes; the run's result."""
    await pilot.press("escape")
    await _ended(app, pilot)
    res = app.session.last_run
    assert res is not None and res.ok, res.message
    assert text_of(app, "#exec-outcome").startswith("COMPLETED")
    return res


async def test_jog_starts_where_a_plan_to_a_boundary_pose_left_the_wrist(console) -> None:
    """A plan to a pose no cover region holds (the planner grew a region around it) leaves
    the wrist there; the jog starts from it (the runtime grows its own region around the
    start), the start is not shown clamped, and the jog ends completed."""
    from tests.runtime.test_follow_runtime import BOUNDARY_NODE

    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _jog_after_a_plan_to(app, pilot, BOUNDARY_NODE)
        ws = app.session.wrist.ensure_workspace()
        assert ws.cover is not None and not ws.cover.containing(np.asarray(BOUNDARY_NODE), tol=1e-3)
        assert "not clamped" in text_of(app, "#jog-target")
        await _end_completed(app, pilot)


async def test_a_refused_jog_keeps_its_reason_on_the_screen(console) -> None:
    from spm_console.errors import BadInputError

    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _homed_on_step5(app, pilot)

        def refuse(**_: Any) -> None:
            raise BadInputError("live following cannot start from here: a test's reason")

        app.session.following.follow = refuse  # type: ignore[method-assign,assignment]
        await pilot.press("j")
        await until(pilot, lambda: isinstance(app.screen, ExecuteScreen) and not app.moving,
                    "the refusal")
        await settle(pilot)
        out = text_of(app, "#exec-outcome")
        assert out.startswith("LIVE JOG REFUSED (nothing moved)")
        assert "a test's reason" in out
        await pilot.press("p")  # another key: the status line moves on, the reason stays
        assert "a test's reason" in text_of(app, "#exec-outcome")


async def test_jog_starts_from_the_papers_goal_a_servo_tick_beyond_the_grid(console) -> None:
    """The paper's goal θ2 = 155° is the grid's edge; the servo settles on the tick 0.04°
    beyond it. The jog is not refused: the runtime moves the wrist just inside first."""
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        edge = float(app.session.wrist.ensure_workspace().axes_deg[1][-1])
        goal = (66.80, edge, 131.48)
        jog, settled = await _jog_after_a_plan_to(app, pilot, goal)
        assert settled[1] > edge  # the case: settled beyond the grid
        # the target starts just inside the grid, not where no region reaches
        assert jog.target.theta_deg[1] < edge and "not clamped" in text_of(app, "#jog-target")
        await pilot.press("m", "down")  # per joint; θ2 one step in
        assert jog.target.mode == "joint"
        want = jog.target.theta_deg.copy()
        assert want[1] < edge - 0.5 * jog.target.step_deg
        res = await _end_completed(app, pilot)
        np.testing.assert_allclose(res.final_deg, want, atol=SETTLED_DEG)
