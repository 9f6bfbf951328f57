"""The command palette (ctrl+p) lists every action of the console from any step: the
steps, help, settings, quit, the E-stop, and every step's own operations ("Plan: Solve"),
which switch to their step first."""

from __future__ import annotations

from typing import Any

from textual.binding import Binding
from textual.command import CommandPalette

from spm_console.tui.app import SETTINGS_TITLE
from spm_console.tui.widgets.steps import STEPS
from tests.support.console_helpers import settle, status_of

SIZE = (120, 40)

#: What each step offers (its own keys), by the words the operator reads in its footer.
OPERATIONS = {
    "commission": {"Start"},
    "connect": {"Connect", "Home", "Read", "Torque", "Jog−", "Jog+", "Reboot", "Identify"},
    "fk": {"FK", "IK", "Modes", "Current"},
    "workspace": {"Load", "Rebuild", "Cancel build", "Check"},
    "plan": {"Solve", "Plot", "Save", "Open plan"},
    "execute": {"Execute", "Preview", "Plot", "Live jog"},
    "logs": {"Refresh", "Open run", "Filter", "Plot", "Joint"},
}


def _declared(mode: str, app: Any) -> set[str]:
    """The descriptions the step's class declares, straight from its BINDINGS."""
    out = set()
    for b in type(app).MODES[mode].__dict__["BINDINGS"]:
        assert isinstance(b, Binding)
        if b.action.partition("(")[0] not in ("leave_field", "move_focus"):
            out.add(b.description)
    return out


async def test_the_palette_lists_every_step_s_actions_from_any_step(console: Any) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        for mode, ops in OPERATIONS.items():
            assert _declared(mode, app) == ops, mode  # the table above is complete
        for here in ("connect", "plan"):
            await app.action_step(here)
            await pilot.pause()
            titles = {c.title for c in app.get_system_commands(app.screen)}
            for s in STEPS:
                assert f"Step {s.key}: {s.title}" in titles
                if s.mode != here:
                    assert {f"{s.title}: {op}" for op in OPERATIONS[s.mode]} <= titles, s.mode
                else:  # the current step's own, under their plain names
                    assert OPERATIONS[s.mode] <= titles
            assert {"Keys", "Quit", SETTINGS_TITLE, "E-STOP"} <= titles


async def test_a_palette_command_of_another_step_switches_there_and_runs(console: Any) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        assert app.current_mode == "connect"
        await pilot.press("ctrl+p")
        await pilot.pause()
        assert isinstance(app.screen, CommandPalette)
        await pilot.press(*"Plan: Solve")
        await settle(pilot)
        await pilot.press("enter")
        await settle(pilot, timeout_s=60)
        assert app.current_mode == "plan"
        assert app.session.plans.plan is not None, status_of(app)
        assert "solved in" in status_of(app)


async def test_the_palette_e_stop_says_when_nothing_moves(console: Any) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        said: list[str] = []
        notify = app.notify
        app.notify = lambda message, **kw: (said.append(str(message)),  # type: ignore[method-assign]
                                            notify(message, **kw))[1]
        estop = next(c for c in app.get_system_commands(app.screen) if c.title == "E-STOP")
        assert "nothing moves now" in estop.help
        await estop.callback()  # type: ignore[misc]
        await pilot.pause()
        assert said == ["E-STOP: nothing moves now."]


async def test_the_palette_finds_the_settings_by_grid_and_by_profile(console: Any) -> None:
    """The palette matches titles only: the settings' title names what they set."""
    from textual.fuzzy import Matcher as Fuzzy

    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        titles = [c.title for c in app.get_system_commands(app.screen)]
        for query in ("grid", "profile", "grid step", "settings"):
            found = [t for t in titles if Fuzzy(query).match(t) > 0]
            assert SETTINGS_TITLE in found, (query, found)
        await pilot.press("ctrl+p")
        await pilot.pause()
        await pilot.press(*"grid step")
        await settle(pilot)
        await pilot.press("enter")
        await settle(pilot)
        from spm_console.tui.screens.settings import SettingsScreen

        assert isinstance(app.screen, SettingsScreen)
