"""Quitting asks first (q again or y quits, n or esc stays), and never happens while the
wrist moves: q is then refused with a notice, the motion goes on to its end."""

from __future__ import annotations

import time

import pytest

from spm_console.tui.screens.base import StepScreen
from spm_console.tui.widgets.confirm import QuitConfirm
from tests.support.console_helpers import burst, settle
from tests.tui.test_small_terminal import screen_text

SIZE = (100, 30)


async def test_q_asks_first_and_n_or_esc_stays(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        for stay in ("n", "escape"):
            await pilot.press("q")
            await pilot.pause()
            assert isinstance(app.screen, QuitConfirm)  # a single q does not quit
            footer = screen_text(app).splitlines()[-1]  # the footer names the dialog's keys
            assert "q/y Quit" in footer and "n Stay" in footer and "Yes" not in footer, footer
            await pilot.press(stay)
            await pilot.pause()
            assert isinstance(app.screen, StepScreen) and app.is_running
        await pilot.press("q", "q")  # q again quits
    assert app.return_code == 0
    assert app.session.bus is None  # the session closed


async def test_q_then_y_quits_and_so_does_a_burst_of_two_q(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("q", "y")
    assert app.return_code == 0
    again = console()
    async with again.run_test(size=SIZE) as pilot:
        await settle(pilot)
        burst(again, "q", "q")  # typed ahead: the second q reaches the question
        await pilot.pause(0.5)
    assert again.return_code == 0


@pytest.mark.usefixtures("paced_clock")  # it acts while the wrist moves: real-time pace
async def test_q_while_the_wrist_moves_is_refused_and_the_motion_ends_normally(console) -> None:
    app = console(initial_deg=(85.0, 150.0, 110.0))  # 50° from home: 2.5 s at 20°/s
    said: list[str] = []
    async with app.run_test(size=SIZE) as pilot:
        notify = app.notify
        app.notify = lambda message, **kw: (said.append(str(message)),  # type: ignore[method-assign]
                                            notify(message, **kw))[1]
        await settle(pilot)
        await pilot.press("h", "y")
        t_end = time.monotonic() + 30.0
        while not app.session.moving.is_set():  # the homing has started (bounded: never a hang)
            assert time.monotonic() < t_end, "the homing did not start within 30 s"
            await pilot.pause(0.02)
        await pilot.press("q")
        assert app.moving and app.session.moving.is_set()  # still under way
        assert not isinstance(app.screen, QuitConfirm)
        assert any("press SPACE to stop it before quitting" in m for m in said), said
        await settle(pilot)
        assert app.is_running
        run = app.session.last_run
        assert run is not None and run.ok and app.session.homed  # not stopped by the q
