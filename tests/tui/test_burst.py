"""Keys that arrive in one burst (type-ahead, an unbracketed paste, tmux send-keys) reach
the field that has the focus when each key comes: a value typed before a Tab stays whole
in its field, the value after it goes whole into the next one."""

from __future__ import annotations

from typing import Any

import pytest
from textual import events

from spm_console.tui.widgets.angles import AnglesInput
from tests.support.console_helpers import burst, settle

SIZE = (160, 48)


async def _plan_goal(pilot: Any) -> AnglesInput:
    await settle(pilot)
    await pilot.press("3")  # the planner needs the workspace
    await settle(pilot)
    await pilot.press("4")
    await pilot.pause()
    return pilot.app.screen.query_one("#goal-values", AnglesInput)


async def _empty_first_goal_field(pilot: Any) -> AnglesInput:
    """The plan step's goal fields, the first one emptied and focused."""
    goal = await _plan_goal(pilot)
    goal.fields[0].focus()
    goal.fields[0].value = ""
    await pilot.pause()
    return goal


async def test_a_burst_with_tabs_fills_each_field_with_its_own_value(console: Any) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        goal = await _empty_first_goal_field(pilot)
        burst(app, "127.5", "tab", "83.2", "tab", "85.2")
        await settle(pilot)
        assert [f.value for f in goal.fields] == ["127.5", "83.2", "85.2"]
        assert app.screen.focused is goal.fields[2]
        footer = {k: b.binding for k, b in app.screen.active_bindings.items() if b.binding.show}
        assert footer["tab"].description == "Fields" and footer["escape"].description == "Leave"
        burst(app, "shift+tab", "84", "shift+tab", "128")  # and back
        await settle(pilot)
        assert [f.value for f in goal.fields] == ["128", "84", "85.2"]


async def test_editing_keys_in_a_burst_act_where_they_were_typed(console: Any) -> None:
    """A field's own keys (backspace, ctrl+u, …) act between the characters around them,
    in the field they were typed into: "127.6⌫5" is 127.5, and the ctrl+u typed after a
    tab empties the next field before "83.2" goes in (not after)."""
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        goal = await _empty_first_goal_field(pilot)
        burst(app, "127.6", "backspace", "5", "tab", "end", "ctrl+u", "83.2")
        await settle(pilot)
        assert [f.value for f in goal.fields][:2] == ["127.5", "83.2"]
        assert app.screen.focused is goal.fields[1]


async def test_a_burst_after_leaving_a_field_reaches_the_screen_not_the_field(
        console: Any) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        goal = await _plan_goal(pilot)
        goal.fields[1].focus()
        await pilot.pause()
        before = goal.fields[1].value
        burst(app, "escape", "6")  # leave the field, then the Logs step
        await settle(pilot)
        assert app.current_mode == "logs"
        assert goal.fields[1].value == before


@pytest.mark.parametrize("pasted", ["127.5 83.2 85.2", "127.5\n83.2\n85.2"],
                         ids=["one line", "several lines"])
async def test_a_paste_stays_whole_in_the_focused_field(console: Any, pasted: str) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        goal = await _empty_first_goal_field(pilot)
        app.post_message(events.Paste(pasted))
        await settle(pilot)
        # as pasted (lines joined by spaces), in the field that had the focus, marked
        # invalid with the reason; the other fields untouched
        assert [f.value for f in goal.fields] == ["127.5 83.2 85.2", "110", "105"]
        assert goal.fields[0].has_class("-invalid")
        assert app.screen.focused is goal.fields[0]


async def test_esc_in_an_open_dropdown_closes_its_list_and_keeps_the_focus(
        console: Any) -> None:
    from textual.widgets import Select

    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _plan_goal(pilot)
        method = app.screen.query_one("#method", Select)
        method.focus()
        await pilot.press("enter")  # open the list
        await pilot.pause()
        assert method.expanded
        await pilot.press("escape")
        await pilot.pause()
        assert not method.expanded and app.screen.focused is method
        await pilot.press("escape")  # then esc leaves the dropdown
        await pilot.pause()
        assert app.screen.focused is None
