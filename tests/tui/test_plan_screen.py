"""Step 4: plans solved in a worker from the form; the same numbers as the core."""

from __future__ import annotations

import numpy as np
from textual.widgets import Input, Select

from spm_console.config.models import servo_model_of
from spm_console.core.planning.mvn import solve_mvn
from spm_console.core.regions.choice import region_containing
from spm_console.tui.widgets.angles import AnglesInput
from tests.support.console_helpers import settle, status_of, text_of

SIZE = (130, 42)


async def _to_plan(pilot) -> None:  # type: ignore[no-untyped-def]
    await settle(pilot)
    await pilot.press("3")  # the workspace (from the cache)
    await settle(pilot)
    await pilot.press("4")
    await pilot.pause()


async def test_mvn_from_current_pose_matches_the_core(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _to_plan(pilot)
        app.screen.query_one("#steps", Input).value = "60"
        await pilot.press("s")
        await settle(pilot)
        plan = app.session.plans.plan
        assert plan is not None and plan.kind == "mvn" and plan.N == 60, status_of(app)
        s = app.session
        ref = solve_mvn(servo_model_of(s.profile), np.full(3, 135.0), [95, 110, 105], 60,
                        region_containing(s.wrist.workspace, np.full(3, 135.0), np.array([95, 110, 105.])),
                        s.profile.limits.vmax_degps)
        np.testing.assert_allclose(plan.reference_deg, ref.reference_deg, atol=1e-6)
        out = text_of(app, "#plan-text")
        assert "N = 60 × 0.02 s = 1.20 s" in out and "constraints verified" in out
        assert "press 5" in status_of(app).lower()


async def test_minimum_time_from_an_orientation(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _to_plan(pilot)
        app.screen.query_one("#goal-kind", Select).value = "rpy"
        app.screen.query_one("#goal-values", AnglesInput).set_values([10, 5, -15])
        app.screen.query_one("#method", Select).value = "mintime"
        await pilot.press("s")
        await settle(pilot, timeout_s=120)
        plan = app.session.plans.plan
        assert plan is not None and plan.kind == "mintime", status_of(app)
        np.testing.assert_allclose(plan.reference_deg[-1], app.session.wrist.ik([10, 5, -15]), atol=1e-6)
        assert float(np.abs(plan.velocity_degps).max()) <= 50.0 + 1e-6
        out = text_of(app, "#plan-text")
        assert out.startswith("Minimum time: ")
        # the minimum-time certificate: N − 1 steps proven infeasible
        assert plan.certificate is not None and plan.certificate.N == plan.N - 1
        assert plan.certificate.certificate is not None and plan.certificate.certificate.valid
        # said in plain words: what was proven, not the certificate's numbers
        n = plan.N - 1
        assert (f"fastest possible: no reference reaches the goal in N−1 = {n} steps "
                f"({n * plan.Ts:.2f} s) within these limits") in out, out
        assert "Farkas" not in out and "‖x‖" not in out


async def test_form_errors_are_messages(console) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _to_plan(pilot)
        app.screen.query_one("#steps", Input).value = ""
        await pilot.press("s")
        await settle(pilot)
        assert "steps N: empty, type a whole number of steps" in status_of(app)
        app.screen.query_one("#steps", Input).value = "100"
        # within the servo limits (60…160°), outside the grid (65…155°)
        app.screen.query_one("#goal-values", AnglesInput).set_values([62, 135, 135])
        await pilot.press("s")
        await settle(pilot)
        msg = status_of(app)
        assert app.session.plans.plan is None
        assert "goal θ = [62.00, 135.00, 135.00]° is NOT feasible" in msg, msg
        assert "outside the workspace grid" in msg


async def test_solving_before_the_workspace_step_loads_the_workspace(console) -> None:
    """Planning is not refused until step 3 was visited: the solve loads the workspace."""
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        assert app.session.wrist.workspace is None
        await pilot.press("4", "s")
        await settle(pilot)
        assert app.session.wrist.workspace is not None and app.session.plans.plan is not None, status_of(app)


async def test_the_free_first_box_shows_its_mark_only_when_on(console) -> None:
    """Off it is an empty box (Textual draws the X in both states, colour alone tells them
    apart); space ticks it and the X appears."""
    app = console()
    async with app.run_test(size=(80, 24)) as pilot:
        await _to_plan(pilot)
        box = app.screen.query_one("#free-first")
        assert box.value is False  # type: ignore[attr-defined]
        assert "X" not in str(box.render())
        box.focus()
        await pilot.press("space")
        assert box.value is True  # type: ignore[attr-defined]
        assert "X" in str(box.render())


async def test_start_and_goal_fields_are_named_with_their_unit(console) -> None:
    """Each angle field has its name and unit above it, which follow the pose kind (θ or
    roll/pitch/yaw) — also once the fields hold text (the placeholder then hides)."""
    app = console()
    async with app.run_test(size=(80, 24)) as pilot:
        await _to_plan(pilot)
        goal = app.screen.query_one("#goal-values", AnglesInput)

        def names() -> list[str]:
            return [str(n.render()) for n in goal.query(".angle-name")]

        assert names() == ["θ1 (°)", "θ2 (°)", "θ3 (°)"]
        app.screen.query_one("#goal-kind", Select).value = "rpy"
        await pilot.pause()
        assert names() == ["roll (°)", "pitch (°)", "yaw (°)"]
        assert all(f.value for f in goal.fields)  # the placeholders are hidden
        for n, f in zip(goal.query(".angle-name"), goal.fields, strict=True):
            assert n.region.bottom == f.region.y and n.region.x == f.region.x  # right above
