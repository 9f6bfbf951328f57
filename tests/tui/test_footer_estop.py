"""While the wrist moves, the footer shows the E-stop first: at 80 columns the keys after
the first few are cut, and SPACE must never be among them."""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

from tests.support.console_helpers import settle, status_of
from tests.tui.test_small_terminal import screen_text

SMALL = (80, 24)


@pytest.mark.usefixtures("paced_clock")  # acts while the wrist homes
async def test_the_footer_shows_space_estop_while_homing_at_80_columns(console: Any) -> None:
    app = console(initial_deg=(85.0, 150.0, 110.0))  # 50° from home: 2.5 s at 20°/s
    async with app.run_test(size=SMALL) as pilot:
        await settle(pilot)
        footer = screen_text(app).splitlines()[-1]
        assert "E-STOP" not in footer  # only while the wrist moves
        await pilot.press("h", "y")
        for _ in range(200):  # until the motion has begun (no fixed sleep)
            if app.moving:
                break
            await asyncio.sleep(0.01)
        assert app.moving, status_of(app)
        await pilot.pause(0.1)  # the footer recomposes after the bindings changed
        footer = screen_text(app).splitlines()[-1]
        assert footer.lstrip().startswith("SPACE E-STOP"), footer
        await pilot.press("space")
        await settle(pilot)
        assert not app.moving and "homing stopped" in status_of(app)
        await pilot.pause(0.1)
        assert "E-STOP" not in screen_text(app).splitlines()[-1]
