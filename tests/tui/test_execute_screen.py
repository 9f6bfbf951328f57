"""Step 5 on the emulated bus: confirmation, live telemetry, E-stop, faults, the log."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest
from textual.widgets import DataTable

from spm_console.devices.emulator.faults import parse_fault
from spm_console.errors import ExitCode
from spm_console.motion.logs.runlog import list_runs, load_run
from tests.support.console_helpers import MotionSpy, confirm_execute, settle, status_of, text_of

pytestmark = pytest.mark.usefixtures("paced_clock")  # acts while the wrist moves

SIZE = (130, 42)


async def _homed_with_plan(pilot, steps: int) -> None:  # type: ignore[no-untyped-def]
    """Homed, workspace loaded and an MVN plan solved — through the session the screens use
    (those steps' screens have their own tests); then the execute screen."""
    from spm_console.services.wrist_service import PoseSpec

    app = pilot.app
    s = app.session
    await settle(pilot)
    assert s.bus is not None, status_of(app)
    await asyncio.to_thread(s.home)
    assert s.homed
    await asyncio.to_thread(s.wrist.load_workspace)
    await asyncio.to_thread(s.plans.solve, "mvn", PoseSpec("current"),
                            PoseSpec("theta", (95.0, 110.0, 105.0)), s.theta_deg, steps)
    await pilot.press("5")
    await pilot.pause()


async def test_execute_needs_a_plan(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("5", "x")
        await settle(pilot)
        assert "no plan" in status_of(app)
        assert type(app.screen).__name__ == "ExecuteScreen"
        await pilot.press("4")
        await _homed_with_plan(pilot, 50)  # back on step 5 with a plan: the refusal is gone
        assert "no plan" not in status_of(app), status_of(app)


async def test_execute_runs_the_plan_live_and_logs_it(console, tmp_path) -> None:
    app = console()
    spy = MotionSpy()
    async with app.run_test(size=SIZE, message_hook=spy.hook) as pilot:
        spy.attach(app)
        await _homed_with_plan(pilot, 50)
        spy.press_while_moving = "1"  # steps are locked while the wrist moves
        n_before = len(spy.banner_at_telemetry)
        await confirm_execute(pilot)
        await settle(pilot)
        assert type(app.screen).__name__ == "ExecuteScreen"
        assert spy.press_while_moving == ""  # the key was sent during the motion
        assert set(spy.screens_at_telemetry[n_before:]) == {"ExecuteScreen"}
        assert spy.moving == [True, False]  # the execution (homing went through the session)
        assert len(spy.banner_at_telemetry) >= n_before + 5 and all(spy.banner_at_telemetry)
        res = app.session.last_run
        assert res is not None and res.ok, status_of(app)
        np.testing.assert_allclose(res.final_deg, [95, 110, 105], atol=0.3)
        table = app.screen.query_one("#joints", DataTable)
        measured = [float(table.get_row_at(i)[2].strip().rstrip("°")) for i in range(3)]
        np.testing.assert_allclose(measured, [95, 110, 105], atol=1.0)  # last telemetry shown
        out = text_of(app, "#exec-outcome")
        assert out.startswith("COMPLETED (exit code 0)") and str(res.log_dir) in out
        run = load_run(res.log_dir)
        assert run.meta["outcome"] == "completed" and run.rows >= 51
        # the time shown here is the one the Logs step lists for the run (its servo loop)
        from spm_console.tui.screens.logs import RUN_COLUMNS, run_row

        loop = run_row(run.info)[RUN_COLUMNS.index("loop")]
        assert text_of(app, "#exec-clock") == f"done: servo loop {loop}"
        assert "press 6" in text_of(app, "#hint-line")
        assert "F5 ✔" in text_of(app, "#steps-line")


async def test_space_is_an_estop_during_execution(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _homed_with_plan(pilot, 150)  # 3 s of motion
        await confirm_execute(pilot)
        await pilot.pause(0.2)
        await pilot.press("space")
        await settle(pilot)
        res = app.session.last_run
        assert res is not None and res.exit_code == ExitCode.STOP_ESTOP
        assert text_of(app, "#exec-outcome").startswith("STOPPED (exit code 20)")
        assert "F5 ✔" not in text_of(app, "#steps-line")  # a stopped run is no tick
        run = load_run(res.log_dir)
        assert run.meta["outcome"] == "stopped"
        # the key press reached the loop in its own process within a period; hold within 2
        stop = next(e for e in run.events if e["event"] == "stop")
        ts = app.session.profile.servo.ts_s
        # (the paced clock moves a period at a time: a press at one period's instant is seen at
        # the next, exactly ts later, give or take the rounding of the two clock readings)
        assert stop["detected_t"] - stop["requested_t"] <= ts + 1e-9
        assert stop["done_t"] - stop["detected_t"] <= 2 * ts + 1e-9
        # stopped before the end, and it holds short of the goal
        assert res.stats.stop.detected_t < app.session.motion_total_s - 0.3
        assert np.abs(app.session.read_position() - [95, 110, 105]).max() > 2.0


async def test_a_stalled_joint_stops_the_run_with_the_reason(console, tmp_path) -> None:
    app = console(faults=[parse_fault("stall:2")])
    async with app.run_test(size=SIZE) as pilot:
        await _homed_with_plan(pilot, 60)
        await confirm_execute(pilot)
        await settle(pilot)
        res = app.session.last_run
        assert res is not None and res.exit_code == ExitCode.STOP_TRACKING, status_of(app)
        assert "joint 2" in status_of(app)
        runs = list_runs(tmp_path / "logs")
        assert [r.meta["outcome"] for r in runs if not r.info.preview] == ["completed", "stopped"]
        # the preview on the twin (the same emulated fault) said so before the question
        assert [r.meta["outcome"] for r in runs if r.info.preview] == ["stopped"]


async def test_execute_before_homing_is_refused_and_logs_share_the_cli_schema(
        console, tmp_path, capsys) -> None:
    """The runtime's rules through the console: homed first; the run log's metadata has the
    keys a CLI ``execute`` writes (tests/e2e/test_same_rules.py runs the CLI and scripts)."""
    from spm_console.services.wrist_service import PoseSpec

    app = console()
    async with app.run_test(size=SIZE) as pilot:
        s = app.session
        await settle(pilot)
        await asyncio.to_thread(s.wrist.load_workspace)
        await asyncio.to_thread(s.plans.solve, "mvn", PoseSpec("current"),
                                PoseSpec("theta", (125.0, 130.0, 128.0)), s.theta_deg, 30)
        await pilot.press("5", "x")
        await settle(pilot)
        if type(app.screen).__name__ == "ConfirmScreen":
            await pilot.press("y")
            await settle(pilot)
        assert "the wrist is not homed: press 1, then h" in status_of(app)
        assert not s.homed and s.last_run is None
        await asyncio.to_thread(s.home)
        await confirm_execute(pilot)
        await settle(pilot)
        assert s.last_run is not None and s.last_run.ok, status_of(app)
        console_meta = load_run(s.last_run.log_dir).meta
    from spm_console.cli.main import main

    plan_file = tmp_path / "p.json"
    from spm_console.store.plan_file import save_plan

    save_plan(s.plans.plan, plan_file)
    code = main(["execute", "--plan", str(plan_file), "--sim", "--json",
                 "--logs", str(tmp_path / "cli")])
    assert code == 0, capsys.readouterr()
    [cli_run] = [r for r in list_runs(tmp_path / "cli") if r.meta["kind"] == "execute"]
    cli_meta = load_run(cli_run.path).meta
    assert set(console_meta) == set(cli_meta)
    assert console_meta["homing"] == cli_meta["homing"] == "done"


async def test_x_previews_the_run_on_the_twin_before_it_asks(console, tmp_path) -> None:
    """The preview shows under the plan and as the plot before "Execute the plan?"; nothing
    moved; its log is marked preview; no again moves nothing; x from the same place asks
    at once (the same preview); the run then ends where the preview said."""
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _homed_with_plan(pilot, 60)
        s = app.session
        before, homing = s.read_position(), s.last_run
        await pilot.press("x")
        await settle(pilot)
        assert type(app.screen).__name__ == "LongConfirm", status_of(app)
        body = text_of(app, "#confirm-body")
        assert "Preview on the twin" in body and "the run completes" in body
        assert "final error against the goal" in body and "closest to the edge of P′" in body
        await pilot.press("n")
        await settle(pilot)
        shown = text_of(app, "#exec-preview")
        assert shown.startswith("Preview on the twin") and "final error" in shown
        view = app.screen.query_one("#exec-plot")
        assert view._title.startswith("preview: planned θ*")
        np.testing.assert_allclose(s.read_position(), before, atol=0.1)  # nothing moved
        assert s.last_run is homing  # no run on the wrist
        pv = app.screen.preview
        assert pv is not None and pv.plan is s.plans.plan
        [log] = [r for r in list_runs(tmp_path / "logs") if r.info.preview]
        assert log.meta["kind"] == "execute" and log.meta["clock"] == "simulated"
        await pilot.press("x")  # from the same place: the same preview, asked at once
        await pilot.pause()
        assert type(app.screen).__name__ == "LongConfirm"
        await pilot.press("y")
        await settle(pilot)
        assert app.screen.preview is pv
        assert len([r for r in list_runs(tmp_path / "logs") if r.info.preview]) == 1
        res = s.last_run
        assert res is not None and res.ok, status_of(app)
        assert pv.final_error_deg is not None
        np.testing.assert_allclose(res.final_deg, pv.plan.reference_deg[-1] + pv.final_error_deg,
                                   atol=0.2)
        # another plan: the preview of the last one is no longer shown
        from spm_console.services.wrist_service import PoseSpec

        await asyncio.to_thread(s.plans.solve, "mvn", PoseSpec("current"),
                                PoseSpec("theta", (100.0, 115.0, 110.0)), s.theta_deg, 40)
        await pilot.press("4", "5")
        await settle(pilot)
        assert app.screen.preview is None
        assert not app.screen.query_one("#exec-preview").display
