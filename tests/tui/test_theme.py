"""A theme chosen in the palette styles every step: the one shown, the ones visited before and
the ones first visited after (new steps start from the current stylesheet)."""

from __future__ import annotations

from textual.color import Color
from textual.widgets import Footer

from spm_console.tui.app import SpmConsoleApp
from spm_console.tui.widgets.steps import STEPS
from tests.support.console_helpers import settle

SIZE = (120, 40)


def _theme_colours(app: SpmConsoleApp) -> tuple[Color, Color]:
    """(the screen's background, the footer's background) of the step shown."""
    return app.screen.styles.background, app.screen.query_one(Footer).styles.background


async def test_a_new_theme_styles_steps_visited_before_and_after(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        first = app.current_mode
        for s in STEPS[: len(STEPS) // 2]:  # some steps visited before the change
            await pilot.press(s.fkey)
            await settle(pilot)
        await pilot.press(next(s.fkey for s in STEPS if s.mode == first))
        await settle(pilot)
        before = _theme_colours(app)
        assert before[0] == Color.parse(app.get_css_variables()["background"])
        light = next(n for n, t in app.available_themes.items() if not t.dark)
        app.theme = light
        await settle(pilot)
        want = Color.parse(app.get_css_variables()["background"])
        assert want != before[0]
        seen = {first: _theme_colours(app)}
        for s in STEPS:  # every step, most of them first visited now
            await pilot.press(s.fkey)
            await settle(pilot)
            assert app.current_mode == s.mode
            seen[s.mode] = _theme_colours(app)
        await pilot.press(next(s.fkey for s in STEPS if s.mode == first))
        await settle(pilot)
        seen["again"] = _theme_colours(app)
        assert {m: c[0] for m, c in seen.items()} == {m: want for m in seen}
        footers = {c[1] for c in seen.values()}
        assert len(footers) == 1 and before[1] not in footers
