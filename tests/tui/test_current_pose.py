"""Step 4 with "current pose" as the start: the start fields show the θ a solve uses (the
last reading of the servos, read again just before solving), never an older one, and the
solved plan states its start."""

from __future__ import annotations

from typing import Any

import numpy as np
from textual.widgets import Input, Select

from spm_console.tui.widgets.angles import AnglesInput
from tests.support.console_helpers import settle, status_of, text_of

SIZE = (160, 48)
#: Where the emulated servos stand at start (feasible, not home), deg.
THERE = (120.0, 128.0, 124.0)


def shown(app: Any) -> list[float]:
    return [float(f.value) for f in app.screen.query_one("#start-values", AnglesInput).fields]


async def _to_plan(pilot: Any) -> None:
    await settle(pilot)  # connected: the first reading of the servos is in
    await pilot.press("3")
    await settle(pilot)
    await pilot.press("4")
    await settle(pilot)


async def test_start_fields_show_the_pose_the_solve_uses(console: Any) -> None:
    app = console(initial_deg=THERE)
    async with app.run_test(size=SIZE) as pilot:
        await _to_plan(pilot)
        assert app.screen.query_one("#start-kind", Select).value == "current"
        assert app.session.theta_deg is not None
        np.testing.assert_allclose(shown(app), THERE, atol=0.05)  # the emulator's pose
        # the servos moved since the last reading the console holds (a stale record)
        app.session.theta_deg = np.array([100.0, 100.0, 100.0])
        app.screen.query_one("#steps", Input).value = "40"
        await pilot.press("s")
        await settle(pilot)
        plan = app.session.plans.plan
        assert plan is not None, status_of(app)
        # solved from where the servos are (read before solving), and the fields say so
        np.testing.assert_allclose(plan.position_deg[0], THERE, atol=0.05)
        np.testing.assert_allclose(shown(app), plan.position_deg[0], atol=0.005)
        out = text_of(app, "#plan-text")
        start = ", ".join(f"{v:.2f}" for v in plan.position_deg[0])
        assert f"start θ = [{start}]° (read from the servos just before solving)" in out, out


async def test_start_fields_follow_the_pose_between_visits(console: Any) -> None:
    app = console(initial_deg=THERE)
    async with app.run_test(size=SIZE) as pilot:
        await _to_plan(pilot)
        start = app.screen.query_one("#start-values", AnglesInput)
        assert start.is_disabled
        np.testing.assert_allclose(shown(app), THERE, atol=0.05)
        await pilot.press("1", "h")  # home the wrist from the connect step
        await pilot.press("y")
        await settle(pilot, timeout_s=60)
        assert app.session.homed, status_of(app)
        await pilot.press("4")
        await settle(pilot)
        home = app.session.profile.home.theta_deg
        np.testing.assert_allclose(shown(app), app.session.theta_deg, atol=0.005)
        np.testing.assert_allclose(shown(app), home, atol=0.5)


async def test_typed_start_comes_back_when_theta_is_chosen_again(console: Any) -> None:
    app = console(initial_deg=THERE)
    async with app.run_test(size=SIZE) as pilot:
        await _to_plan(pilot)
        kind = app.screen.query_one("#start-kind", Select)
        start = app.screen.query_one("#start-values", AnglesInput)
        kind.value = "theta"
        await pilot.pause()
        for field, text in zip(start.fields, ["101.5", "abc", "99"], strict=True):
            field.value = text
        await pilot.pause()
        kind.value = "current"
        await pilot.pause()
        np.testing.assert_allclose(shown(app), THERE, atol=0.05)
        kind.value = "theta"
        await pilot.pause()
        assert [f.value for f in start.fields] == ["101.5", "abc", "99"]
        assert start.fields[1].has_class("-invalid")


async def test_start_fields_follow_the_servos_while_the_plan_step_shows(
        console: Any) -> None:
    """The wrist moves while the plan step is on screen (here: homed by the session, which
    the screen is not told about): the fields catch up from the servos by themselves."""
    import asyncio

    from spm_console.tui.screens.plan import POSE_EVERY_S

    app = console(initial_deg=THERE)
    async with app.run_test(size=SIZE) as pilot:
        await _to_plan(pilot)
        np.testing.assert_allclose(shown(app), THERE, atol=0.05)
        await asyncio.to_thread(app.session.home)
        home = app.session.profile.home.theta_deg
        loop = asyncio.get_running_loop()
        t_end = loop.time() + 20 * POSE_EVERY_S
        while loop.time() < t_end and not np.allclose(shown(app), home, atol=0.5):
            await pilot.pause(POSE_EVERY_S / 5)
        np.testing.assert_allclose(shown(app), home, atol=0.5)
