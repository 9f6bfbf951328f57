"""Step 0's form refuses what it cannot start, with the reason under the fields and nothing
started (no dialog, no worker): a servo bus or IMU port that is empty, overlong, with spaces or
the same twice, the IMU stage without the IMU, a payload mass that is no weighed mass in
(0, 2] kg or comes without the IMU stage. Nothing moves: the console's emulated bus runs on the
suite's simulated clock."""

from __future__ import annotations

import pytest
from textual.widgets import RichLog

from spm_console.config.checks import MAX_PORT_CHARS
from spm_console.tui.screens.commission import CommissionScreen
from spm_console.tui.widgets.checkbox import TickBox
from spm_console.tui.widgets.field import TextField
from tests.support.console_helpers import settle, status_of, text_of

SMALL = (80, 24)


def _fill(app, bus: str, imu: str) -> None:  # type: ignore[no-untyped-def]
    app.screen.query_one("#bus-port", TextField).value = bus
    app.screen.query_one("#imu-port", TextField).value = imu


@pytest.mark.parametrize(("bus", "imu", "jig", "why"), [
    ("", "/dev/ttyUSB1", True, "servo bus: empty"),
    ("/dev/ttyUSB0", "", True, "the IMU stage needs the IMU"),
    ("/dev/ttyUSB0", "   ", True, "IMU port: empty"),
    ("/dev/" + "x" * MAX_PORT_CHARS, "/dev/ttyUSB1", True, f"at most {MAX_PORT_CHARS}"),
    ("/dev/ttyUSB0", "/dev/tty USB1", True, "no spaces"),
    ("/dev/ttyUSB0", "/dev/ttyUSB0", True, "ports of their own"),
])
async def test_bad_ports_are_refused_with_the_reason_and_nothing_starts(
        console, bus: str, imu: str, jig: bool, why: str) -> None:  # type: ignore[no-untyped-def]
    app = console()
    async with app.run_test(size=SMALL) as pilot:
        await settle(pilot)
        await pilot.press("0")
        await settle(pilot)
        assert isinstance(app.screen, CommissionScreen)
        assert app.screen.query_one("#bus-port", TextField).value == ""  # emulated: no prefill
        assert app.screen.query_one("#imu-stage", TickBox).value is True
        _fill(app, bus, imu)
        app.screen.query_one("#jig", TickBox).value = jig
        await pilot.press("s")
        await pilot.pause()
        assert isinstance(app.screen, CommissionScreen)  # no dialog
        assert why in status_of(app) and "nothing started" in status_of(app), status_of(app)
        assert why in text_of(app, "#commission-reason")
        assert app.screen.busy_op == "" and not app.moving
        assert not app.screen.query_one("#stages", RichLog).lines


@pytest.mark.parametrize(("imu", "jig", "mass", "imu_stage", "why"), [
    ("/dev/ttyUSB1", True, "0", True, "payload mass"),
    ("/dev/ttyUSB1", True, "2.5", True, "payload mass"),
    ("/dev/ttyUSB1", True, "abc", True, "payload mass"),
    ("/dev/ttyUSB1", True, "0.3", False, "needs the IMU stage"),
    # nothing would zero the wrist: refused before the questions (the CLI's usage error)
    ("", False, "", False, "nothing would zero the wrist"),
])
async def test_options_that_cannot_work_are_refused_and_nothing_starts(
        console, imu: str, jig: bool, mass: str, imu_stage: bool,  # type: ignore[no-untyped-def]
        why: str) -> None:
    app = console()
    async with app.run_test(size=SMALL) as pilot:
        await settle(pilot)
        await pilot.press("0")
        await settle(pilot)
        _fill(app, "/dev/ttyUSB0", imu)
        app.screen.query_one("#jig", TickBox).value = jig
        app.screen.query_one("#imu-stage", TickBox).value = imu_stage
        app.screen.query_one("#payload-kg", TextField).value = mass
        await pilot.press("s")
        await pilot.pause()
        assert isinstance(app.screen, CommissionScreen)  # no dialog
        assert why in status_of(app) and "nothing started" in status_of(app), status_of(app)
        assert why in text_of(app, "#commission-reason")
        assert app.screen.busy_op == "" and not app.moving


async def test_the_reason_follows_the_form_as_it_is_mended(console) -> None:  # type: ignore[no-untyped-def]
    """Shown by s, the reason under the form changes as the form is edited, and goes once the
    form can start (it stayed as it was until the next s)."""
    app = console()
    async with app.run_test(size=SMALL) as pilot:
        await settle(pilot)
        await pilot.press("0")
        await settle(pilot)
        _fill(app, "/dev/ttyUSB0", "/dev/ttyUSB0")
        await pilot.press("s")
        await pilot.pause()
        assert "ports of their own" in text_of(app, "#commission-reason")
        _fill(app, "/dev/ttyUSB0", "")
        await pilot.pause()
        reason = text_of(app, "#commission-reason")
        assert "the IMU stage needs the IMU" in reason and "ports of their own" not in reason
        app.screen.query_one("#imu-stage", TickBox).value = False
        app.screen.query_one("#jig", TickBox).value = True
        await pilot.pause()
        assert text_of(app, "#commission-reason").strip() == ""
        assert isinstance(app.screen, CommissionScreen)  # nothing started by editing
        assert app.screen.busy_op == ""
