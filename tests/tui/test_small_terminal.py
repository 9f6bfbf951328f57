"""80×24 is fully usable: the step bar shows every step, every panel scrolls by keyboard
(the FK screen's eight assembly modes down to the last), plots keep a readable height."""

from __future__ import annotations

from collections.abc import AsyncIterator
from typing import Any

from rich.cells import cell_len
from textual.widget import Widget
from textual.widgets import Input

from spm_console.tui.widgets.plot import PlotView
from spm_console.tui.widgets.steps import STEPS
from tests.support.console_helpers import screen_text, settle, status_of, text_of

SMALL = (80, 24)


async def each_step(app: Any, pilot: Any) -> AsyncIterator[Any]:
    """Switch to every step in turn by its F-key (settled): yields the step."""
    await settle(pilot)
    for s in STEPS:
        await pilot.press(s.fkey)
        await settle(pilot)
        assert app.current_mode == s.mode
        yield s


async def test_the_step_bar_shows_every_step_at_80_columns(console) -> None:
    app = console()
    async with app.run_test(size=SMALL) as pilot:
        async for s in each_step(app, pilot):
            line = text_of(app, "#steps-line")
            assert cell_len(line) <= SMALL[0]
            for t in STEPS:
                assert f"{t.fkey_display} " in line, (s.mode, line)
            # the six operating steps by their titles; step 0 (commissioning) by its key
            operating = [t for t in STEPS if t.key != "0"]
            assert all(t.short in line for t in operating), (s.mode, line)
            shown = screen_text(app).splitlines()[0]
            assert all(t.short in shown for t in operating), shown


async def test_all_assembly_modes_scroll_into_view_at_80x24(console) -> None:
    app = console()
    async with app.run_test(size=SMALL) as pilot:
        await settle(pilot)
        await pilot.press("2", "m")
        await settle(pilot)
        assert "8 assembly modes" in text_of(app, "#fk-result"), status_of(app)
        assert "8: n =" not in screen_text(app)  # more than the screen holds
        await pilot.press("end")
        await pilot.pause()
        assert "8: n =" in screen_text(app)
        await pilot.press("home")
        await pilot.pause()
        assert "8: n =" not in screen_text(app)
        for _ in range(40):  # line by line, too
            await pilot.press("down")
        await pilot.pause()
        assert "8: n =" in screen_text(app)


async def test_scroll_keys_scroll_the_panel_around_a_focused_field(console) -> None:
    app = console()
    async with app.run_test(size=SMALL) as pilot:
        await settle(pilot)
        await pilot.press("2", "m")
        await settle(pilot)
        await pilot.press("tab")  # into θ1: PgDn still scrolls the page around it
        assert app.focused is not None
        body: Widget = app.screen.query_one(".body", Widget)
        assert body.scroll_y == 0
        await pilot.press("pagedown")
        await pilot.pause()
        assert body.scroll_y > 0


async def test_the_plan_plot_is_readable_at_80x24(console) -> None:
    app = console()
    async with app.run_test(size=SMALL) as pilot:
        await settle(pilot)
        await pilot.press("3")
        await settle(pilot)
        await pilot.press("4", "s")
        await settle(pilot)
        assert app.session.plans.plan is not None, status_of(app)
        plot = app.screen.query_one("#plan-plot", PlotView)
        assert plot.content_size.height >= 12
        assert plot.content_size.width >= 70
        await pilot.press("end")
        await pilot.pause()
        shown = screen_text(app)
        assert "references θ*" in shown and "┌" in shown  # title and the plot's frame


async def test_fields_are_one_line_on_short_terminals_only(console) -> None:
    app = console()
    async with app.run_test(size=SMALL) as pilot:
        await settle(pilot)
        await pilot.press("4")
        await pilot.pause()
        steps = app.screen.query_one("#steps", Input)
        assert steps.compact and steps.outer_size.height == 1
        await pilot.resize_terminal(160, 48)
        await pilot.pause()
        assert not steps.compact and steps.outer_size.height == 3
        assert "Connect/home" in text_of(app, "#steps-line")  # full titles again


def test_every_step_fits_80_columns_when_all_are_done() -> None:
    from spm_console.tui.widgets.steps import step_labels

    operating = [s for s in STEPS if s.key != "0"]  # step 0 (commissioning) is never ticked
    done = {s.mode for s in operating}
    for s in STEPS:
        line = step_labels(s.mode, done, SMALL[0])
        assert line.cell_length <= SMALL[0]
        if s.key != "0":
            assert all(f"{t.fkey_display} ✔ {t.short}" in line.plain for t in operating)
        else:
            assert f"{s.fkey_display} {s.short}" in line.plain, line.plain
    assert "Connect/home" in step_labels("plan", done, 120).plain


async def test_the_reason_under_an_invalid_field_shows_at_80x24(console: Any) -> None:
    """Compact fields are one line high; the reason line under them still appears."""
    from spm_console.tui.widgets.angles import AnglesInput
    from tests.support.console_helpers import settle

    app = console()
    async with app.run_test(size=(80, 24)) as pilot:
        await settle(pilot)
        await pilot.press("2")
        await settle(pilot)
        theta = app.screen.query_one("#theta", AnglesInput)
        theta.fields[0].value = "12,5"
        await pilot.pause()
        reason = theta.query_one(".entry-reason")
        # on screen inside its field group (a one-line group used to clip it away)
        assert reason.display and reason.region.height >= 1
        assert theta.region.contains_region(reason.region), (theta.region, reason.region)
        assert "decimals take a point" in str(reason.render())
        theta.fields[0].value = "127.5"
        await pilot.pause()
        assert not reason.display


async def test_every_steps_footer_keys_show_whole_at_80_columns(console: Any) -> None:
    """The connect step has nine keys: at 80 columns the footer drops its padding and the
    palette's entry (ctrl+p stays bound) so none is cut; at 160 columns both come back."""
    from textual.widgets._footer import FooterKey

    app = console()
    async with app.run_test(size=SMALL) as pilot:
        async for s in each_step(app, pilot):
            await pilot.pause(0.05)  # the footer recomposes after a resize or a step change
            last = screen_text(app).splitlines()[-1]
            keys = [k.description for k in app.screen.query(FooterKey) if k.description]
            assert len(keys) >= (3 if s.key == "0" else 4), (s.mode, keys)  # 0: Start, ?, q
            for d in keys:
                assert d in last, (s.mode, d, last)
            assert cell_len(last.rstrip()) <= SMALL[0]
        await pilot.resize_terminal(160, 48)
        await settle(pilot)
        await pilot.pause(0.05)
        assert "palette" in screen_text(app).splitlines()[-1]


async def test_notices_never_cover_the_status_line_or_the_step_bar(console: Any) -> None:
    from textual.widgets._toast import Toast

    app = console()
    async with app.run_test(size=SMALL, notifications=True) as pilot:
        await settle(pilot)
        app.screen.status.ok("homed: executed 18 cycles (0.36 s). Log: /somewhere/long")
        app.notify("Settings applied: a notice several words long to take some room.",
                   title="Settings", timeout=30)
        await pilot.pause(0.3)
        toasts = list(app.screen.query(Toast))
        assert toasts, "no notice shown"
        status = app.screen.query_one("#status").region
        steps = app.screen.query_one("#steps-line").region
        for t in toasts:
            assert not t.region.overlaps(status), (t.region, status)
            assert not t.region.overlaps(steps), (t.region, steps)


async def test_a_step_key_while_the_wrist_moves_says_why_nothing_happens(console: Any) -> None:
    """The steps are locked while the wrist moves: a step key says so (it was silently
    ignored, the key disabled before its action could explain)."""
    from textual.widgets._toast import Toast

    app = console()
    async with app.run_test(size=SMALL, notifications=True) as pilot:
        await settle(pilot)
        before = app.current_mode
        app.moving = True
        await pilot.press("2")
        await pilot.pause(0.3)
        assert app.current_mode == before
        said = " ".join(str(t.render()) for t in app.screen.query(Toast))
        assert "The wrist is moving" in said, said
        app.moving = False
        await pilot.press("2")
        await settle(pilot)
        assert app.current_mode != before
