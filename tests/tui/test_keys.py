"""Keys that cannot collide with typing: digits and letters typed into a field or a dropdown
stay there; F-keys (and ctrl+digit) switch steps from anywhere; `?` and the command palette
list every action, generated from the bindings."""

from __future__ import annotations

import io
from typing import Any

from rich.console import Console
from textual.binding import Binding
from textual.command import CommandPalette
from textual.widgets import Input, Select, Static

from spm_console.tui.screens.help import HelpScreen
from spm_console.tui.widgets.confirm import ConfirmScreen
from spm_console.tui.widgets.steps import STEPS
from tests.support.console_helpers import settle, status_of, text_of

SIZE = (120, 40)


async def test_digits_typed_into_a_field_stay_in_the_field(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("2")
        assert app.current_mode == "fk"
        field = app.screen.query_one("#theta-0", Input)
        field.focus()
        field.value = ""
        await pilot.press(*"85.25", "1", "3", "4", "6")
        await pilot.pause()
        assert app.current_mode == "fk"
        assert field.value == "85.251346"
        assert app.focused is field


async def test_letters_typed_into_a_field_do_not_run_screen_actions(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("2")
        field = app.screen.query_one("#theta-0", Input)
        field.focus()
        before = text_of(app, "#fk-result")
        await pilot.press("m", "f", "i", "q", "question_mark")
        await settle(pilot)
        assert app.current_mode == "fk" and app.is_running
        assert not isinstance(app.screen, HelpScreen)
        assert text_of(app, "#fk-result") == before  # neither f (FK) nor m (modes) ran


async def test_digits_and_letters_in_a_focused_dropdown_do_nothing(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("4")
        assert app.current_mode == "plan"
        select = app.screen.query_one("#start-kind", Select)
        select.focus()
        await pilot.pause()
        status = status_of(app)
        await pilot.press(*"85.25", "s", "w", "q")
        await settle(pilot)
        assert app.current_mode == "plan" and app.is_running
        assert select.value == "current" and app.focused is select
        assert status_of(app) == status  # s did not solve, w did not save
        assert app.session.plans.plan is None


async def test_fkeys_and_ctrl_digits_switch_steps_from_inside_a_field(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("f2")
        assert app.current_mode == "fk"
        app.screen.query_one("#theta-1", Input).focus()
        await pilot.press("f4")
        assert app.current_mode == "plan"
        app.screen.query_one("#start-kind", Select).focus()
        await pilot.press("f6")
        assert app.current_mode == "logs"
        await pilot.press("f4")
        app.screen.query_one("#steps", Input).focus()
        await pilot.press("ctrl+2")
        assert app.current_mode == "fk"


async def test_digits_switch_steps_once_the_field_is_left(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("2")
        app.screen.query_one("#rpy-0", Input).focus()
        await pilot.press("3")
        assert app.current_mode == "fk"
        await pilot.press("escape", "3")
        assert app.current_mode == "workspace"


async def test_a_dialog_keeps_the_step_until_it_is_answered(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("h")
        await pilot.pause()
        assert isinstance(app.screen, ConfirmScreen)
        await pilot.press("f3", "3")
        await pilot.pause()
        assert app.current_mode == "connect" and isinstance(app.screen, ConfirmScreen)
        await pilot.press("n")
        await pilot.press("f3")
        assert app.current_mode == "workspace"


def _descriptions(bindings: list) -> set[str]:
    return {b.description for b in bindings if isinstance(b, Binding) and b.description}


def _help_text(app: Any) -> str:
    """The whole help (also what is scrolled out of view), as plain text."""
    console = Console(width=160, record=True, file=io.StringIO())
    console.print(app.screen.query_one("#help-text", Static).content)
    return console.export_text()


async def test_help_lists_every_binding_of_the_screen_and_the_app(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("4")
        plan_screen = app.screen
        await pilot.press("question_mark")
        await pilot.pause()
        assert isinstance(app.screen, HelpScreen)
        text = _help_text(app)
        wanted = _descriptions(type(plan_screen).BINDINGS) | _descriptions(type(app).BINDINGS)
        assert {"Solve", "Plot", "Save", "Keys", "Quit", "E-STOP"} <= wanted
        for desc in wanted | {"Scroll"}:
            assert desc in text, desc
        for s in STEPS:
            assert f"{s.fkey_display} {s.key} ^{s.key}" in text
        assert "SPACE" in text and "PgDn" in text
        await pilot.press("f3")  # a step key closes the help and switches
        assert app.current_mode == "workspace" and not isinstance(app.screen, HelpScreen)
        await pilot.press("question_mark")
        await pilot.pause()
        assert "Rebuild" in _help_text(app)
        await pilot.press("escape")
        assert not isinstance(app.screen, HelpScreen)


async def test_the_command_palette_lists_and_runs_every_action(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("4")
        titles = {c.title for c in app.get_system_commands(app.screen)}
        wanted = _descriptions(type(app.screen).BINDINGS) | {f"Step {s.key}: {s.title}"
                                                             for s in STEPS}
        assert wanted | {"Keys", "Quit"} <= titles
        assert "E-STOP" in titles  # listed (it says that nothing moves now)
        app.screen.query_one("#steps", Input).focus()
        await pilot.press("ctrl+p")  # from inside a field
        await pilot.pause()
        assert isinstance(app.screen, CommandPalette)
        await pilot.press(*"Step 3")
        await settle(pilot)
        await pilot.press("enter")
        await settle(pilot)
        assert app.current_mode == "workspace"
        await pilot.press("ctrl+p")
        await pilot.pause()
        await pilot.press("f5")  # a step key closes the palette and switches
        await pilot.pause()
        assert app.current_mode == "execute" and not isinstance(app.screen, CommandPalette)
