"""Settings (ctrl+o / F7): the profile and the workspace grid step from inside the console.
The grid step is checked as typed (never altered) and the whole profile at that step before
the confirmation; Apply is refused while the wrist moves; applying closes the session and
exits with a SwitchRequest (``spm-console tui`` then starts the next console)."""

from __future__ import annotations

import io
from pathlib import Path

from rich.console import Console
from textual.widgets import Input, OptionList, Static

from spm_console.tui.app import SETTINGS_TITLE
from spm_console.tui.screens.help import HelpScreen
from spm_console.tui.screens.settings import SettingsScreen, SwitchRequest, list_profiles
from spm_console.tui.widgets.confirm import ConfirmScreen
from tests.conftest import ROOT
from tests.support.console_helpers import settle, text_of

SIZE = (120, 40)
AGILE = ROOT / "profiles" / "agile_wrist.toml"
COAXIAL = ROOT / "profiles" / "coaxial_spm.toml"


def _reason(app) -> str:  # type: ignore[no-untyped-def]
    return text_of(app, "#settings-reason")


async def _open(pilot, key: str = "ctrl+o") -> SettingsScreen:  # type: ignore[no-untyped-def]
    await pilot.press(key)
    await pilot.pause()
    screen = pilot.app.screen
    assert isinstance(screen, SettingsScreen)
    return screen


async def _type_step(pilot, text: str) -> Input:  # type: ignore[no-untyped-def]
    field = pilot.app.screen.query_one("#grid-step", Input)
    field.focus()
    field.value = ""
    await pilot.press(*text)
    await pilot.pause()
    return field


def test_the_list_names_the_repo_profiles_and_a_current_one_elsewhere(tmp_path: Path) -> None:
    elsewhere = tmp_path / "mine.toml"
    elsewhere.write_text(AGILE.read_text(encoding="utf-8").replace(
        'name = "agile_wrist"', 'name = "my_wrist"'), encoding="utf-8")
    broken = tmp_path / "profiles"
    broken.mkdir()
    (broken / "bad.toml").write_text("[profile\n", encoding="utf-8")
    entries = list_profiles(elsewhere, [ROOT / "profiles", broken])
    assert [(e.name, e.step_deg) for e in entries[:2]] == [("agile_wrist", 2.0),
                                                           ("coaxial_spm", 2.0)]
    assert entries[2].error == "not valid TOML" and entries[2].path.name == "bad.toml"
    assert (entries[3].path, entries[3].name) == (elsewhere, "my_wrist")


async def test_ctrl_o_and_f7_open_the_settings_from_anywhere(console) -> None:
    app = console(profile_path=AGILE)
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        screen = await _open(pilot)
        assert "In use: profile agile_wrist" in text_of(app, "#settings-now")
        assert "grid step 2°" in text_of(app, "#settings-now")
        options = screen.query_one("#settings-profiles", OptionList)
        labels = [str(options.get_option_at_index(i).prompt) for i in range(options.option_count)]
        assert any(lab.startswith("agile_wrist") for lab in labels)
        assert any(lab.startswith("coaxial_spm") for lab in labels)
        assert labels[options.highlighted or 0].startswith("agile_wrist")  # the one in use
        assert screen.query_one("#grid-step", Input).value == "2"
        await pilot.press("escape")
        await pilot.pause()
        assert not isinstance(app.screen, SettingsScreen)

        await pilot.press("2")  # from inside a field too (F7 is a priority key)
        app.screen.query_one("#theta-0", Input).focus()
        await _open(pilot, "f7")
        await pilot.press("escape")
        assert app.current_mode == "fk" and app.is_running


async def test_settings_are_listed_in_the_help_and_the_palette(console) -> None:
    app = console(profile_path=AGILE)
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("question_mark")
        await pilot.pause()
        assert isinstance(app.screen, HelpScreen)
        out = Console(width=160, record=True, file=io.StringIO())
        out.print(app.screen.query_one("#help-text", Static).content)
        line = next(x for x in out.export_text().splitlines() if "Settings" in x)
        assert "^o F7" in line and "grid step" in line
        await pilot.press("escape")
        titles = [c.title for c in app.get_system_commands(app.screen)]
        assert SETTINGS_TITLE in titles


async def test_invalid_grid_steps_are_marked_kept_as_typed_and_refused(console) -> None:
    app = console(profile_path=AGILE)
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await _open(pilot)
        for typed, why in (("0", "must be above 0°"), ("45", "outside"),
                           ("1,5", "decimals take a point"), ("q1", "is not a step")):
            field = await _type_step(pilot, typed)
            assert field.value == typed  # never altered
            assert field.has_class("-invalid")
            assert why in text_of(app, "#grid-step-row .entry-reason")
            await pilot.press("enter")  # Apply from the field
            await settle(pilot)
            assert isinstance(app.screen, SettingsScreen)  # still open: refused
            assert _reason(app).startswith("Not applied: grid step Δ")
            assert why in _reason(app)
        # in range, but not a grid of the chosen profile's 90° range: marked as typed too
        for typed, why in (("7", "not a whole number of steps"), ("0.01", "nodes")):
            field = await _type_step(pilot, typed)
            assert field.value == typed and field.has_class("-invalid"), typed
            assert why in text_of(app, "#grid-step-row .entry-reason")
            await pilot.press("enter")
            await settle(pilot)
            assert isinstance(app.screen, SettingsScreen)
            assert why in _reason(app)
        field = await _type_step(pilot, "3")  # a new value: the refusal about the old one goes
        assert _reason(app) == "" and not field.has_class("-invalid")
        assert text_of(app, "#grid-step-row .entry-reason") == ""
        # the settings in use are no change
        await _type_step(pilot, "2.0")
        await pilot.press("enter")
        await settle(pilot)
        assert "already in use" in _reason(app)
    assert app.return_value is None or not isinstance(app.return_value, SwitchRequest)


async def test_settings_refused_while_the_wrist_moves(console) -> None:
    app = console(profile_path=AGILE)
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await _open(pilot)
        await _type_step(pilot, "3")
        app.moving = True  # as during homing or an execution
        await pilot.press("enter")
        await settle(pilot)
        assert isinstance(app.screen, SettingsScreen)
        assert "the wrist is moving" in _reason(app)
        await pilot.press("escape")
        await pilot.pause()
        await pilot.press("ctrl+o")  # not even opened while it moves
        await pilot.pause()
        assert not isinstance(app.screen, SettingsScreen)
        app.moving = False
        await _open(pilot)
        await _type_step(pilot, "3")
        await pilot.press("enter")
        await settle(pilot)
        assert isinstance(app.screen, ConfirmScreen)
        app.moving = True  # a motion started while the question was open
        await pilot.press("y")
        await settle(pilot)
        assert isinstance(app.screen, SettingsScreen)
        assert "the wrist is moving" in _reason(app)
        app.moving = False
    assert not isinstance(app.return_value, SwitchRequest)


async def test_apply_closes_the_session_and_exits_with_the_switch_request(console) -> None:
    app = console(profile_path=AGILE)
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("c", "y")  # connect again: the motion process runs
        await settle(pilot)
        assert app.session.bus is not None
        screen = await _open(pilot)
        options = screen.query_one("#settings-profiles", OptionList)
        options.focus()
        while not str(options.get_option_at_index(options.highlighted or 0).prompt) \
                .startswith("coaxial_spm"):
            await pilot.press("down")
        await pilot.press("enter")  # on to the grid step
        assert app.focused is screen.query_one("#grid-step", Input)
        await pilot.press("backspace", "3")
        await pilot.press("enter")
        await settle(pilot)
        assert isinstance(app.screen, ConfirmScreen)
        assert "coaxial_spm" in text_of(app, "#confirm-body")
        await pilot.press("y")
        await settle(pilot)
    request = app.return_value
    assert isinstance(request, SwitchRequest)
    assert (request.profile_path.resolve(), request.grid_step_deg) == (COAXIAL, 3.0)
    assert app.session.bus is None and app.session.emulator is None  # closed before the exit


async def test_form_values_follow_the_profile_across_a_restart(console, agile) -> None:
    """Remembered per profile name: a restart at another grid step recalls them."""
    from spm_console.config.load import with_grid_step
    from spm_console.tui.app import make_app

    first = console(profile_path=AGILE)
    async with first.run_test(size=SIZE) as pilot:
        await settle(pilot)
        first.form_memory.put("agile_wrist", "plan.steps", "77")  # as a solve remembers it
        assert first.form_memory.save()
        await _open(pilot)
        await _type_step(pilot, "3")
        await pilot.press("enter")
        await settle(pilot)
        await pilot.press("y")
        await settle(pilot)
    request = first.return_value
    assert isinstance(request, SwitchRequest)
    second = make_app(with_grid_step(agile, request.grid_step_deg), viewer=False,
                      logs_root=first.session.logs_root, cache_dir=first.session.cache_dir,
                      profile_path=request.profile_path, note="restarted")
    async with second.run_test(size=SIZE) as pilot:
        await settle(pilot)
        assert second.sub_title == "agile_wrist, grid step 3°"
        await pilot.press("4")
        await settle(pilot)
        assert second.screen.query_one("#steps", Input).value == "77"


def test_form_defaults_lie_inside_every_profiles_servo_limits(agile, coaxial) -> None:  # type: ignore[no-untyped-def]
    from spm_console.config.models import servo_limits_deg
    from spm_console.tui.widgets.rules import AGILE_GOAL_DEG, default_theta_deg

    assert default_theta_deg(agile) == AGILE_GOAL_DEG
    for prof in (agile, coaxial):
        lo, hi = servo_limits_deg(prof)
        th = default_theta_deg(prof)
        assert all(lo[i] <= th[i] <= hi[i] for i in range(3))


async def test_after_a_restart_the_note_names_the_applied_settings_on_screen(console) -> None:
    """The note a restart passes in shows as a toast on the first step, up long enough to
    read while the console connects (it was gone after 8 s)."""
    from textual.widgets._toast import Toast

    from spm_console.tui.app import NOTE_TIMEOUT_S

    note = "Settings applied: profile profiles/coaxial_spm.toml, grid step 3° (the console " \
           "restarted for them)."
    app = console(note=note)
    async with app.run_test(size=(80, 24), notifications=True) as pilot:
        await pilot.pause()
        toasts = list(app.screen.query(Toast))
        assert [str(t.render()) for t in toasts] == [f"Settings\n{note}"]
        assert NOTE_TIMEOUT_S >= 20 and toasts[0]._notification.timeout == NOTE_TIMEOUT_S
