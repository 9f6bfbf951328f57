"""Step 1's live servo health and tools on the emulated bus: the table refreshes by itself
while idle and says "moving" during a motion; torque per joint; jog (homed only, with a
confirmation, a logged motion); reboot clears an injected hardware error."""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
from textual.pilot import Pilot
from textual.widgets import DataTable, Input

from spm_console.devices.emulator.faults import parse_fault
from spm_console.motion.logs.runlog import list_runs
from spm_console.tui.app import SpmConsoleApp
from spm_console.tui.screens.connect import HealthPolled
from tests.support.console_helpers import settle, status_of, text_of

SIZE = (120, 36)


def cell(app: SpmConsoleApp, joint: int, column: str) -> str:
    return str(app.screen.query_one("#servos", DataTable).get_cell(str(joint), column))


async def wait_for_cell(pilot: Pilot[Any], joint: int, column: str, want: str,
                        timeout_s: float = 20.0) -> None:
    """Pause until the table shows ``want`` (no key pressed meanwhile)."""
    app = pilot.app
    for _ in range(int(timeout_s / 0.1)):
        if cell(app, joint, column) == want:
            return
        await pilot.pause(0.1)
    raise AssertionError(f"joint {joint} {column}: {cell(app, joint, column)!r}, never {want!r}")


async def test_the_table_refreshes_by_itself_and_torque_per_joint(console) -> None:
    app = console()
    polls: list[HealthPolled] = []
    async with app.run_test(size=SIZE, message_hook=lambda m: isinstance(m, HealthPolled)
                            and polls.append(m)) as pilot:
        await settle(pilot)
        assert [cell(app, j, "torque") for j in (1, 2, 3)] == ["off", "off", "off"]
        assert cell(app, 1, "position") == "135.00°" and cell(app, 2, "voltage") == "12.0 V"
        assert cell(app, 3, "temperature") == "35 °C" and cell(app, 1, "load") == "+0.00 A"
        assert "live status" in text_of(app, "#health-info")
        # the servo changes behind the screen's back (not through the session's last read)
        bus = app.session.bus
        assert bus is not None
        bus.set_torque(2, True)
        await wait_for_cell(pilot, 2, "torque", "on")  # no `r` pressed: the timer read it
        for _ in range(200):  # and it goes on reading, idle
            if len(polls) >= 3:
                break
            await pilot.pause(0.1)
        assert len(polls) >= 3 and all(not p.error for p in polls)

        # t on joint 3 (↓↓): on at once; off asks first
        await pilot.press("down", "down", "t")
        await settle(pilot)
        assert cell(app, 3, "torque") == "on" and "holds where it is" in status_of(app)
        await pilot.press("t")
        assert type(app.screen).__name__ == "ConfirmScreen"
        await pilot.press("y")
        await settle(pilot)
        assert cell(app, 3, "torque") == "off" and "torque off, joint 3" in status_of(app)


async def test_a_slow_status_read_never_piles_up_requests(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        session = app.session
        real = session.tools.servo_status
        started = threading.Event()
        release = threading.Event()
        calls: list[int] = []

        def stuck() -> Any:  # the first read hangs until released; the others are quick
            calls.append(1)
            if len(calls) == 1:
                started.set()
                release.wait(30)
            return real()

        session.tools.servo_status = stuck  # type: ignore[method-assign]
        for _ in range(200):
            if started.is_set():
                break
            await pilot.pause(0.1)
        assert started.is_set()
        for _ in range(10):  # many timer periods while the read hangs
            await pilot.pause(0.1)
        await pilot.press("down")  # the UI still answers keys
        assert app.screen.query_one("#servos", DataTable).cursor_row == 1
        assert len(calls) == 1  # no second request while the first is out
        release.set()
        for _ in range(200):
            if len(calls) >= 2:
                break
            await pilot.pause(0.1)
        assert len(calls) >= 2  # polling resumed once it answered


async def test_jog_only_when_homed_with_a_confirmation(console, tmp_path) -> None:
    app = console()
    health_lines: list[str] = []

    def hook(message: object) -> None:
        from spm_console.tui.messages import Telemetry

        if isinstance(message, Telemetry) and app.screen.query("#health-info"):
            health_lines.append(text_of(app, "#health-info"))

    async with app.run_test(size=SIZE, message_hook=hook) as pilot:
        await settle(pilot)
        await pilot.press("plus")
        assert type(app.screen).__name__ == "ConnectScreen"  # nothing asked, nothing moved
        assert "not homed" in status_of(app)
        assert list_runs(tmp_path / "logs") == []

        await pilot.press("h", "y")
        await settle(pilot)
        assert app.session.homed, status_of(app)
        assert health_lines and all(line.startswith("moving") for line in health_lines)

        # the step typed stays as typed; an invalid one is refused with its reason
        field = app.screen.query_one("#jog-step", Input)
        field.focus()
        await pilot.press("backspace", "1", "2", ",", "5")
        assert field.value == "12,5"
        # focused, the one-line field keeps no border (a border would take its only line
        # and hide the text being typed)
        assert field.has_focus and field.styles.border_top[0] in ("", "none")
        assert "decimals take a point" in text_of(app, "#jog-note")
        await pilot.press("ctrl+u", *"0.000000000001")  # longer than fits: kept, refused
        assert field.value == "0.000000000001"
        assert "at most 10 are accepted" in text_of(app, "#jog-note")
        await pilot.press("ctrl+u", *"12,5")
        await pilot.press("enter", "minus")  # enter: back to the table, then jog
        assert "jog step is invalid" in status_of(app)
        field.focus()
        await pilot.press("backspace", "backspace", "backspace", "backspace", "2", ".", "5",
                          "enter")
        assert field.value == "2.5" and "by 2.5°" in text_of(app, "#jog-note")

        await pilot.press("down", "minus")  # joint 2 by -2.5°
        assert type(app.screen).__name__ == "ConfirmScreen"
        await pilot.press("n")
        await settle(pilot)
        assert "nothing moved" in status_of(app)
        await pilot.press("minus", "y")
        await settle(pilot)
        assert not app.moving and "joint 2 by -2.5°: done" in status_of(app), status_of(app)
        np.testing.assert_allclose(app.session.read_position(), [135, 132.5, 135], atol=0.1)
        runs = list_runs(tmp_path / "logs")
        assert [r.meta["outcome"] for r in runs] == ["completed", "completed"]
        assert runs[-1].meta["plans"][0]["source"].startswith("jog: joint 2 by -2.5°")
        assert runs[-1].meta["plans"][0]["kind"] == "jog"  # not logged as a homing


async def test_reboot_clears_an_injected_hardware_error(console) -> None:
    app = console(faults=[parse_fault("hwerror:1")])
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        assert cell(app, 1, "hardware") == "0x20 overload" and cell(app, 2, "hardware") == "none"
        await pilot.press("b")
        assert type(app.screen).__name__ == "ConfirmScreen"
        await pilot.press("y")
        await settle(pilot)
        assert cell(app, 1, "hardware") == "none" and cell(app, 1, "torque") == "off"
        assert "joint 1 rebooted" in status_of(app) and "no longer homed" in status_of(app)
        assert not app.session.homed
