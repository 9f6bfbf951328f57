"""A failed solve on the plan step says what to do in the console (which field, which key),
never a shell command: the planner's messages are shared with the CLI."""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import pytest
from textual.widgets import Input, Select

from spm_console.config.schema import Profile
from spm_console.errors import BadInputError, InfeasibleError, Issue, SpmError
from spm_console.services.plan_request import PlanRequest, plan_motion, precheck
from spm_console.tui.screens.base import describe_error
from spm_console.tui.screens.plan_words import next_step
from spm_console.tui.widgets.angles import AnglesInput
from tests.support.console_helpers import settle, status_of, text_of
from tests.support.ws_helpers import agile_workspace

SIZE = (120, 40)
#: What a shell command or option looks like in a message.
CLI = re.compile(r"spm-console|'plan |'workspace |--[a-z]")


@pytest.mark.parametrize(("method", "steps", "vmax", "field"), [
    ("mvn", "2", "50", "'steps N' field"),  # 40° in two 20 ms steps: no reference
    ("mintime", "150", "0.01", "'v_max °/s' field"),  # no horizon is long enough
], ids=["mvn-too-few-steps", "mintime-too-slow"])
async def test_a_failed_solve_says_which_field_to_change(
        console: Any, method: str, steps: str, vmax: str, field: str) -> None:
    app = console()
    said: list[str] = []
    notify = app.notify
    app.notify = lambda message, **kw: (said.append(str(message)),  # type: ignore[method-assign]
                                        notify(message, **kw))[1]
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("4")
        await pilot.pause()
        app.screen.query_one("#goal-values", AnglesInput).set_values([95, 110, 105])
        app.screen.query_one("#method", Select).value = method
        app.screen.query_one("#steps", Input).value = steps
        app.screen.query_one("#vmax", Input).value = vmax
        await pilot.pause()
        await pilot.press("s")
        await settle(pilot, timeout_s=120)
        assert app.session.plans.plan is None
        out, status = text_of(app, "#plan-text"), status_of(app)
        kind = {"mvn": "MVN", "mintime": "minimum-time"}[method]
        assert out.startswith(f"No {kind} plan:\n"), out  # answered with its reason: no failure
        assert "solve failed" not in out + status, out
        for text in (out, status, *said):
            assert not CLI.search(text), text
        next_line = out.split("\nNext: ", 1)[1]
        assert field in next_line and "press s" in next_line, next_line
        assert len([s for s in said if "solve" in s or "N =" in s or "v_max" in s]) <= 1


def test_each_kind_of_failure_gets_its_own_advice(agile: Profile) -> None:
    assert "connect first (press 1 (F1), then c)" in next_step(Issue.POSE_UNKNOWN)
    with pytest.raises(SpmError) as slow:
        precheck(agile, PlanRequest("mintime", np.full(3, 135.0), np.full(3, 95.0),
                                    vmax_degps=0.01))
    assert "use a speed bound of at least" in slow.value.message
    assert "'v_max °/s' field" in next_step(slow.value.issue)
    with pytest.raises(SpmError) as end:
        plan_motion(agile, agile_workspace(), PlanRequest("mvn", np.full(3, 100.0),
                                                          np.array([62.0, 135.0, 135.0])))
    assert end.value.message.startswith("goal θ = [62.00, 135.00, 135.00]° is NOT feasible")
    assert "start or goal fields" in next_step(end.value.issue)
    assert "then press s" in next_step(SpmError("something else went wrong").issue)
    assert "then press s" in next_step(None)


def test_the_advice_follows_the_issue_not_the_words(agile: Profile) -> None:
    """The runtime's errors carry their Issue (the message names no console step); the
    console adds its words and picks its advice by the Issue."""
    from spm_console.services.session import Session
    from spm_console.services.wrist_service import PoseSpec

    with pytest.raises(BadInputError) as exc:
        Session(agile).resolve(PoseSpec("current"))
    assert exc.value.issue is Issue.POSE_UNKNOWN
    assert exc.value.message == "current pose unknown: connect to the servos first"
    assert describe_error(exc.value) == exc.value.message + " (step 1)"
    assert "connect first" in next_step(exc.value.issue)
    # the same words with another issue get that issue's advice
    other = BadInputError(exc.value.message, Issue.TOO_MANY_INSTANTS)
    assert "intersample K field" in next_step(other.issue)
    with pytest.raises(SpmError) as refused:  # tagged where it is raised: below the servo limits
        precheck(agile, PlanRequest("mvn", np.zeros(3), np.full(3, 135.0)))
    assert refused.value.issue is Issue.END_NOT_FEASIBLE
    with pytest.raises(SpmError) as slow:  # a planner refusal: tagged where it is raised too
        precheck(agile, PlanRequest("mintime", np.full(3, 135.0), np.full(3, 95.0),
                                    vmax_degps=0.01))
    assert slow.value.issue is Issue.SPEED_TOO_LOW


@pytest.mark.parametrize(("issue", "field"), [
    (Issue.TOO_FEW_STEPS, "'steps N' field"),
    (Issue.SPEED_TOO_LOW, "'v_max °/s' field"),
    (Issue.TOO_MANY_INSTANTS, "intersample K field"),
    (Issue.END_NOT_FEASIBLE, "start or goal fields"),
])
async def test_the_plan_step_advises_by_the_issue_whatever_the_words(
        console: Any, monkeypatch: pytest.MonkeyPatch, issue: Issue, field: str) -> None:
    """A refusal whose words belong to another kind (here a too-slow minimum-time search's)
    gets the advice of the Issue it carries: the console never reads the message for it."""
    words = ("no plan within N ≤ 5000 steps (100 s): at v_max = 0.01 deg/s the largest joint "
             "move (40°) needs about 4e+03 s; use a speed bound of at least about 0.4 deg/s")

    def refuse(*args: object, **kw: object) -> None:
        raise InfeasibleError(words, issue)

    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        monkeypatch.setattr(app.session.plans, "solve", refuse)
        await pilot.press("4")
        await pilot.pause()
        await pilot.press("s")
        await settle(pilot, timeout_s=60)
        out = text_of(app, "#plan-text")
        assert words in out, out
        next_line = out.split("\nNext: ", 1)[1]
        assert next_line == next_step(issue) and field in next_line, next_line
