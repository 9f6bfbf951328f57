"""Step 1 on the emulated bus: servo status table, homing with confirmation, E-stop."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest
from textual.widgets import DataTable

from spm_console.errors import ExitCode
from spm_console.motion.logs.runlog import list_runs
from tests.support.console_helpers import MotionSpy, settle, status_of, text_of

SIZE = (120, 36)


async def test_connects_on_start_and_lists_each_servo(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        table = app.screen.query_one("#servos", DataTable)
        assert table.row_count == 3
        rows = [table.get_row_at(i) for i in range(3)]
        assert [r[1] for r in rows] == ["1", "2", "3"]  # ids from the profile
        assert all(r[2] == "321" for r in rows)  # MX-106 on protocol 2.0
        assert all(table.get_cell(str(j), "hardware") == "none" for j in (1, 2, 3))
        assert "3 servos answer" in status_of(app)
        assert "press h to home" in text_of(app, "#hint-line")


async def test_reconnecting_the_emulated_bus_says_the_servos_started_again(console) -> None:
    """c on the emulated bus starts new emulated servos (initial pose, torque off): the
    status line says so instead of a plain "connected" beside a wrist that jumped."""
    app = console(initial_deg=(125.0, 140.0, 130.0))
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        assert "started again" not in status_of(app)  # the first connection restarts nothing
        await pilot.press("h", "y")
        await settle(pilot)
        assert app.session.homed, status_of(app)
        await pilot.press("c")
        assert type(app.screen).__name__ == "ConfirmScreen"  # a connected bus: asked first
        await pilot.press("n")
        await settle(pilot)
        assert "still connected: nothing restarted" in status_of(app) and app.session.homed
        await pilot.press("c", "y")
        await settle(pilot)
        status = status_of(app)
        assert "3 servos answer" in status and "servos started again at θ = [" in status, status
        shown = status.split("θ = [")[1].split("]°")[0]
        np.testing.assert_allclose([float(x) for x in shown.split(",")], [125, 140, 130], atol=0.1)
        assert "not homed" in status and not app.session.homed


async def test_home_asks_first_and_no_moves_nothing(console, tmp_path) -> None:
    app = console(initial_deg=(125.0, 140.0, 130.0))
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        assert app.session.bus is not None, status_of(app)
        before = app.session.read_position()
        await pilot.press("h")
        assert type(app.screen).__name__ == "ConfirmScreen"
        await pilot.press("n")
        await settle(pilot)
        assert "nothing moved" in status_of(app)
        assert not app.session.homed
        assert list_runs(tmp_path / "logs") == []
        np.testing.assert_allclose(app.session.read_position(), before, atol=0.1)


async def test_home_moves_to_home_and_logs_the_run(console, tmp_path) -> None:
    app = console(initial_deg=(115.0, 145.0, 130.0))
    spy = MotionSpy()
    async with app.run_test(size=SIZE, message_hook=spy.hook) as pilot:
        spy.attach(app)
        await settle(pilot)
        await pilot.press("h", "y")
        await settle(pilot)
        assert spy.moving == [True, False]
        assert spy.banner_at_telemetry and all(spy.banner_at_telemetry)  # E-stop always shown
        assert not app.screen.query_one(".estop-banner").display
        assert app.session.homed, status_of(app)
        np.testing.assert_allclose(app.session.theta_deg, [135, 135, 135], atol=0.2)
        runs = list_runs(tmp_path / "logs")
        assert len(runs) == 1 and runs[0].meta["outcome"] == "completed"
        assert str(runs[0].path) in status_of(app)
        assert "press 2" in text_of(app, "#hint-line")
        await pilot.press("f2", "f1")  # nothing ran since: the outcome stays
        assert str(runs[0].path) in status_of(app)
        await pilot.press("f2")
        later = await asyncio.to_thread(app.session.tools.jog, 1, 2.0)  # a later run, elsewhere
        assert later.ok
        await pilot.press("f1")
        await settle(pilot)
        assert status_of(app) == ""  # not the homing's outcome, as if it were the last run


@pytest.mark.usefixtures("paced_clock")  # acts while the wrist homes
async def test_space_stops_homing_and_says_so(console, tmp_path) -> None:
    app = console(initial_deg=(85.0, 150.0, 110.0))  # 50° away: 2.5 s at 20°/s
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("h", "y")
        await pilot.pause(0.2)
        await pilot.press("space")
        await settle(pilot)
        assert not app.moving and not app.session.homed
        run = app.session.last_run
        assert run is not None and run.exit_code == ExitCode.STOP_ESTOP
        assert "homing stopped" in status_of(app)
        assert list_runs(tmp_path / "logs")[0].meta["outcome"] == "stopped"
        # stopped before the end of the move, and it holds there, short of home
        assert run.stats.stop.detected_t < app.session.motion_total_s - 0.3
        assert np.abs(app.session.read_position() - 135.0).max() > 2.0


async def test_unreachable_start_is_refused_with_a_reason(console, tmp_path) -> None:
    # θ1 far out: the straight path from home crosses a singularity or leaves the limits
    app = console(initial_deg=(62.0, 158.0, 62.0))
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("h", "y")
        await settle(pilot)
        assert not app.session.homed
        msg = status_of(app)
        assert "Traceback" not in msg and msg, msg
        assert list_runs(tmp_path / "logs") == [] or \
            list_runs(tmp_path / "logs")[0].meta["outcome"] != "completed"
