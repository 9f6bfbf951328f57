"""Number fields keep what the operator typed: shown in full (also at 80×24), checked as
typed, marked invalid with the reason beside the field, and every action that would use
an invalid field refused with that reason."""

from __future__ import annotations

from typing import Any

import pytest
from textual.widgets import Select, Static

from spm_console.core.bounds import N_MAX
from spm_console.errors import BadInputError
from spm_console.tui.widgets.angles import AnglesInput
from spm_console.tui.widgets.number import FIELD_CHARS, NumberField, NumberRow
from spm_console.tui.widgets.rules import rpy_rules, steps_rule, theta_rules, vmax_rule
from tests.support.console_helpers import settle, status_of, text_of

SMALL = (80, 24)
LARGE = (160, 48)


# ------------------------------------------------------------------ the rules, without a screen
def test_rules_accept_numbers_as_written(agile: Any) -> None:
    th2 = theta_rules(agile)[1]
    assert th2.parse("127.53") == 127.53
    assert th2.parse(" 95 ") == 95.0  # surrounding blanks are not part of the number
    assert rpy_rules()[0].parse("\u22125") == -5.0  # the minus sign the console prints
    assert steps_rule().parse("150") == 150 and steps_rule().parse("1e3") == 1000
    assert vmax_rule(agile).parse("1e-3") == 0.001
    assert vmax_rule(agile).parse(f"{agile.limits.vmax_degps:g}") == agile.limits.vmax_degps


@pytest.mark.parametrize(("rule", "text", "reason"), [
    ("theta2", "250", "θ2: 250 is outside the servo limits 60…160°"),
    ("theta2", "12,5", "θ2: '12,5' is not a number; decimals take a point: 12.5"),
    ("theta2", "abc", "θ2: 'abc' is not a number of degrees"),
    ("theta2", "", "θ2: empty, type a number of degrees"),
    ("theta2", "1_10", "θ2: '1_10' is not a number of degrees"),
    ("theta2", "nan", "θ2: 'nan' is not a number of degrees"),
    ("theta2", "1e400", "θ2: 1e400 is outside the servo limits 60…160°"),
    ("theta2", "95.0000001", f"θ2: 10 characters, at most {FIELD_CHARS} are accepted"),
    ("steps", "1e9", f"steps N: 1e9 is outside 2…{N_MAX}"),
    ("steps", "2.5", "steps N: 2.5 must be a whole number"),
    ("steps", "1.5", "steps N: 1.5 must be a whole number"),  # not "outside 2…": below 2 too
    ("steps", "1", f"steps N: 1 is outside 2…{N_MAX}"),
    ("vmax", "0", "v_max: 0 must be above 0°/s"),
    ("vmax", "300", "v_max: 300 is above the profile's planning limit 50°/s"),
    ("roll", "181", "roll: 181 is outside -180…180°"),
])
def test_rules_refuse_with_a_reason(agile: Any, rule: str, text: str, reason: str) -> None:
    r = {"theta2": theta_rules(agile)[1], "steps": steps_rule(), "vmax": vmax_rule(agile),
         "roll": rpy_rules()[0]}[rule]
    assert r.reason(text).startswith(reason), r.reason(text)
    with pytest.raises(BadInputError):
        r.parse(text)


def test_vmax_bound_is_the_lower_of_rated_speed_and_planning_limit(agile: Any) -> None:
    fast = agile.model_copy(update={"limits": agile.limits.model_copy(
        update={"vmax_degps": 1000.0})})
    assert vmax_rule(fast).reason("270") == ""
    assert vmax_rule(fast).reason("271") == ("v_max: 271 is above the servo's rated speed "
                                             "270°/s (MX-106, 12 V)")


# ------------------------------------------------------------------ on the screens
def screen_lines(app: Any) -> list[str]:
    """What the terminal shows, line by line."""
    return [strip.text for strip in app.screen._compositor.render_strips()]


async def type_into(pilot: Any, field: NumberField, text: str) -> None:
    """Focus ``field``, empty it and type ``text`` key by key."""
    field.focus()
    await pilot.pause()
    field.value = ""
    await pilot.press(*text)
    await pilot.pause()


def shown_in_full(app: Any, field: NumberField) -> str:
    """The text on screen where ``field`` draws its value."""
    r = field.content_region
    return screen_lines(app)[r.y][r.x:r.x + len(field.value)]


def reason_under(widget: Any) -> str:
    line = widget.query_one(".entry-reason", Static)
    return str(line.render()) if line.display else ""


async def _to(pilot: Any, step: str) -> None:
    await settle(pilot)
    pilot.app.screen.set_focus(None)  # step keys act outside the fields
    if step == "4":
        await pilot.press("3")  # the planner needs the workspace
        await settle(pilot)
    await pilot.press(step)
    await pilot.pause()


@pytest.mark.slow  # 15 s per size: eight texts typed key by key on three screens (CI runs it)
@pytest.mark.parametrize("size", [SMALL, LARGE])
async def test_typed_text_stays_as_typed_and_shows_in_full(console: Any, size: Any) -> None:
    texts = ["12,5", "1e-3", "abc", "2.5", "1e9", "100000", "-127.53", "-95.12345"]
    assert len(texts[-1]) == FIELD_CHARS
    app = console()
    async with app.run_test(size=size) as pilot:
        for step in ("2", "3", "4"):
            await _to(pilot, step)
            if step == "4":  # the goal fields take θ; the start ones are used with "θ" too
                app.screen.query_one("#start-kind", Select).value = "theta"
                await pilot.pause()
            fields = list(app.screen.query(NumberField))
            assert fields
            for field in fields:
                assert field.type == "text"  # never type="number" (it drops characters)
            for text in texts:  # key by key into one field of the screen
                await type_into(pilot, fields[0], text)
                assert fields[0].value == text, (fields[0].id, fields[0].value, text)
                assert shown_in_full(app, fields[0]) == text, (step, fields[0].id, size)
            for field in fields[1:]:  # every field is wide enough for the longest
                field.focus()  # scrolled into view
                field.value = texts[-1]
                await pilot.pause()
                assert shown_in_full(app, field) == texts[-1], (step, field.id, size)


async def test_a_text_longer_than_its_field_shows_its_start_once_left(console) -> None:
    """Twelve digits in a θ field: refused with the reason, and once the field is left it
    shows the text from its first character (not the tail, a plausible number)."""
    text = "123456789012"
    app = console()
    async with app.run_test(size=SMALL) as pilot:
        await _to(pilot, "2")
        field = app.screen.query_one(NumberField)
        await type_into(pilot, field, text)
        assert field.value == text and field.has_class("-invalid")
        app.screen.set_focus(None)
        await pilot.pause()
        r = field.content_region
        shown = screen_lines(app)[r.y][r.x:r.x + r.width].strip()
        assert len(shown) >= 9 and text.startswith(shown), shown


async def test_invalid_fields_are_marked_with_the_reason_and_refuse_the_solve(console) -> None:
    app = console()
    async with app.run_test(size=SMALL) as pilot:
        await _to(pilot, "4")
        goal = app.screen.query_one("#goal-values", AnglesInput)
        steps = app.screen.query_one("#steps-row", NumberRow)
        vmax = app.screen.query_one("#vmax-row", NumberRow)
        await pilot.press("s")  # a plan from the defaults, which a refused solve must drop
        await settle(pilot)
        assert app.session.plans.plan is not None, status_of(app)
        assert "F4 ✔" in text_of(app, "#steps-line")
        for widget, field, text, reason in [
            (goal, goal.fields[1], "250", "goal θ2: 250 is outside the servo limits 60…160°"),
            (goal, goal.fields[0], "12,5", "goal θ1: '12,5' is not a number"),
            (goal, goal.fields[2], "ab", "goal θ3: 'ab' is not a number of degrees"),
            (steps, steps.field, "1e9", f"steps N: 1e9 is outside 2…{N_MAX}"),
            (steps, steps.field, "1.5", "steps N: 1.5 must be a whole number"),
            (vmax, vmax.field, "0", "v_max: 0 must be above 0°/s"),
        ]:
            before = field.value
            await type_into(pilot, field, text)
            assert field.has_class("-invalid"), (field.id, text)
            assert reason_under(widget).startswith(reason), reason_under(widget)
            await pilot.press("escape", "s")  # leave the field, ask to solve
            await settle(pilot)
            assert status_of(app).startswith(f"Solve refused (no plan now): {reason}"), \
                status_of(app)
            assert app.session.plans.plan is None  # nothing solved, the previous plan dropped
            assert text_of(app, "#plan-text").startswith("No plan: the solve was refused.")
            assert "F4 ✔" not in text_of(app, "#steps-line")  # the step bar says so too
            field.value = before  # fixed: the mark and the reason go away
            await pilot.pause()
            assert not field.has_class("-invalid") and reason_under(widget) == ""


async def test_unused_fields_neither_mark_nor_refuse(console) -> None:
    """Start "current pose" ignores the start fields; minimum time ignores N."""
    app = console()
    async with app.run_test(size=LARGE) as pilot:
        await _to(pilot, "4")
        start = app.screen.query_one("#start-values", AnglesInput)
        kind = app.screen.query_one("#start-kind", Select)
        kind.value = "theta"  # typed as θ, then "current pose" chosen: the text waits
        await pilot.pause()
        start.fields[0].value = "abc"
        kind.value = "current"
        app.screen.query_one("#method", Select).value = "mintime"
        await pilot.pause()
        steps = app.screen.query_one("#steps-row", NumberRow)
        steps.field.value = "2.5"
        await pilot.pause()
        assert start.is_disabled and steps.is_disabled
        assert not any(f.has_class("-invalid") for f in start.fields)
        assert reason_under(start) == ""
        assert not steps.field.has_class("-invalid") and reason_under(steps) == ""
        # used again: judged again
        app.screen.query_one("#start-kind", Select).value = "theta"
        await pilot.pause()
        assert start.fields[0].has_class("-invalid")
        assert reason_under(start).startswith("start θ1: 'abc' is not a number")


async def test_orientation_ik_cannot_reach_is_refused_beside_the_field(console) -> None:
    app = console()
    async with app.run_test(size=SMALL) as pilot:
        await _to(pilot, "2")
        rpy = app.screen.query_one("#rpy", AnglesInput)
        await type_into(pilot, rpy.fields[1], "80")  # pitch 80°: θ2 beyond its servo limit
        reason = reason_under(rpy)
        assert reason.startswith("roll/pitch/yaw: IK gives θ2 = "), reason
        assert "outside the servo limits 60…160°" in reason
        assert all(f.has_class("-invalid") for f in rpy.fields)
        await pilot.press("escape", "i")
        await settle(pilot)
        assert status_of(app).startswith("IK refused: roll/pitch/yaw: IK gives θ2"), status_of(app)
        assert app.is_running
        await type_into(pilot, rpy.fields[1], "10")
        assert reason_under(rpy) == "" and not any(f.has_class("-invalid") for f in rpy.fields)


async def test_fk_and_check_refuse_while_invalid(console) -> None:
    app = console()
    async with app.run_test(size=SMALL) as pilot:
        await _to(pilot, "2")
        theta = app.screen.query_one("#theta", AnglesInput)
        await type_into(pilot, theta.fields[1], "250")
        await pilot.press("enter")  # Enter in a field asks for FK
        await settle(pilot)
        assert status_of(app).startswith(
            "FK refused: θ2: 250 is outside the servo limits 60…160°"), status_of(app)
        assert theta.fields[1].value == "250"  # still as typed
        await pilot.press("escape", "3")
        await settle(pilot)
        check = app.screen.query_one("#check-theta", AnglesInput)
        await pilot.press("k")  # a verdict for the valid default θ first
        await settle(pilot)
        assert text_of(app, "#ws-check").startswith("θ = "), text_of(app, "#ws-check")
        await type_into(pilot, check.fields[0], "1e9")
        await pilot.press("enter")
        await settle(pilot)
        assert status_of(app).startswith(
            "Check refused: θ1: 1e9 is outside the servo limits 60…160°"), status_of(app)
        # the verdict of the θ checked before is gone with the refusal
        assert text_of(app, "#ws-check").startswith("No verdict: the check was refused.")


async def test_a_too_long_number_is_refused_without_claiming_what_fits(console) -> None:
    """At 80×24 the plan's angle fields are wider than the accepted length: the refusal
    names the accepted length, not a number of characters that "fit" (which depends on the
    layout)."""
    app = console()
    async with app.run_test(size=SMALL) as pilot:
        await _to(pilot, "4")
        goal = app.screen.query_one("#goal-values", AnglesInput)
        await type_into(pilot, goal.fields[0], "95.0000001")
        assert goal.fields[0].content_region.width > FIELD_CHARS + 1  # more than 9 fit here
        why = reason_under(goal)
        assert why == f"goal θ1: 10 characters, at most {FIELD_CHARS} are accepted", why
        assert "fit" not in why


def test_an_open_lower_bound_reads_the_same_in_both_refusals() -> None:
    """0 "must be above 0°" and 15 "is outside (0, 10]°": not "outside 0…10°", which would
    make 0 look accepted."""
    from spm_console.tui.widgets.servo_health import JOG_STEP_RULE

    assert JOG_STEP_RULE.reason("0").endswith("0 must be above 0°")
    assert JOG_STEP_RULE.reason("15").endswith(f"15 is outside (0, {JOG_STEP_RULE.hi:g}]°")
    assert JOG_STEP_RULE.reason("2.5") == ""
