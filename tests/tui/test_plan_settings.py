"""Plan settings within reach: options, a saved plan opened, typed values remembered."""

from __future__ import annotations

import asyncio
from pathlib import Path

from textual.widgets import Checkbox, Input

from spm_console.services.wrist_service import PoseSpec
from spm_console.store.plan_file import save_plan
from tests.support.console_helpers import settle, status_of, text_of

SIZE = (130, 42)


async def test_options_reach_the_solver_and_typed_values_come_back(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("f4")
        await settle(pilot)
        scr = app.screen
        scr.query_one("#steps", Input).value = "060"
        scr.query_one("#intersample", Input).value = "3"
        scr.query_one("#free-first", Checkbox).value = True
        await pilot.pause()
        await pilot.press("s")  # no workspace step visited: solving loads it
        await settle(pilot)
        plan = app.session.plans.plan
        assert plan is not None, status_of(app)
        assert plan.N == 60 and plan.options is not None
        assert plan.options.intersample == 3 and plan.options.hold_first is False
    again = console()  # a new session of the same profile
    async with again.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("f4")
        await settle(pilot)
        scr = again.screen
        assert scr.query_one("#steps", Input).value == "060"  # as typed, not reformatted
        assert scr.query_one("#intersample", Input).value == "3"
        assert scr.query_one("#free-first", Checkbox).value is True


async def test_a_saved_plan_opens_verified_and_a_bad_file_changes_nothing(
        console, tmp_path: Path) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        s = app.session
        await asyncio.to_thread(s.wrist.load_workspace)
        plan = await asyncio.to_thread(s.plans.solve, "mvn", PoseSpec("home"),
                                       PoseSpec("theta", (125.0, 130.0, 128.0)), s.theta_deg, 40)
        path = tmp_path / "saved.json"
        save_plan(plan, path)
        s.plans.plan = None
        await pilot.press("f4")
        await settle(pilot)
        await pilot.press("o")
        await pilot.pause()
        field = app.screen.query_one("#ask-path", Input)
        field.value = str(path)
        await pilot.press("enter")
        await settle(pilot)
        assert s.plans.plan is not None and s.plans.source == str(path), status_of(app)
        assert "verified" in status_of(app)
        # the title names the plan's real ends (it said "from the file → from the file")
        title = text_of(app, "#plan-text").splitlines()[0]
        assert title == "MVN: θ = [135.00, 135.00, 135.00]° → θ = [125.00, 130.00, 128.00]°"
        assert f"opened from {path}" in text_of(app, "#plan-text")
        opened = s.plans.plan
        await pilot.press("o")
        await pilot.pause()
        app.screen.query_one("#ask-path", Input).value = str(tmp_path / "nope.json")
        await pilot.press("enter")
        await settle(pilot)
        assert s.plans.plan is opened and "current plan is unchanged" in status_of(app)
