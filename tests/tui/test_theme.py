"""A theme chosen in the palette styles every step: the one shown, one visited before and one
first visited after (a new step starts from the current stylesheet)."""

from __future__ import annotations

from typing import Any

from textual.color import Color
from textual.pilot import Pilot
from textual.widgets import Footer

from spm_console.tui.app import SpmConsoleApp
from spm_console.tui.widgets.steps import STEPS
from tests.support.console_helpers import settle

SIZE = (120, 40)


def _theme_colours(app: SpmConsoleApp) -> tuple[Color, Color]:
    """(the screen's background, the footer's background) of the step shown."""
    return app.screen.styles.background, app.screen.query_one(Footer).styles.background


async def _show(app: SpmConsoleApp, pilot: Pilot[Any], mode: str) -> tuple[Color, Color]:
    await pilot.press(next(s.fkey for s in STEPS if s.mode == mode))
    await settle(pilot)
    assert app.current_mode == mode
    return _theme_colours(app)


async def test_a_new_theme_styles_steps_visited_before_and_after(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        first = app.current_mode
        before = await _show(app, pilot, "fk")  # a step visited before the change
        assert before[0] == Color.parse(app.get_css_variables()["background"])
        await _show(app, pilot, first)
        light = next(n for n, t in app.available_themes.items() if not t.dark)
        app.theme = light
        await settle(pilot)
        want = Color.parse(app.get_css_variables()["background"])
        assert want != before[0]
        seen = {first: _theme_colours(app)}
        for mode in ("fk", "logs", first):  # visited before; first visited now; shown at the change
            seen[f"{mode} after"] = await _show(app, pilot, mode)
        assert {m: c[0] for m, c in seen.items()} == {m: want for m in seen}
        footers = {c[1] for c in seen.values()}
        assert len(footers) == 1 and before[1] not in footers
