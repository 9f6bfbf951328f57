"""Nothing stale: a failed action clears the result it would have replaced (text, plot, 3D
path preview, the session's plan), says what happened and what to do next."""

from __future__ import annotations

from typing import Any

import pytest
from textual.widgets import Input, Select

from spm_console.errors import CacheError, SpmError
from spm_console.tui.widgets.angles import AnglesInput
from tests.support.console_helpers import settle, status_of, text_of

SIZE = (120, 40)


async def _plan_screen(pilot: Any) -> None:
    await settle(pilot)
    await pilot.press("3")
    await settle(pilot)
    await pilot.press("4")
    await pilot.pause()


@pytest.mark.parametrize(("method", "steps", "goal", "why"), [
    # the case: minimum time after an MVN plan; N is not used by it (left invalid)
    ("mintime", "2.5", [62, 135, 135], "goal θ = [62.00, 135.00, 135.00]° is NOT feasible"),
    # the solver itself finds no plan: 40° in two 20 ms steps under 50°/s
    ("mvn", "2", [95, 110, 105], ""),
], ids=["mintime", "mvn"])
async def test_a_failed_solve_clears_the_plan_it_would_have_replaced(
        console: Any, method: str, steps: str, goal: list[float], why: str) -> None:
    app = console()
    cleared: list[bool] = []
    app.view.clear_path = lambda: cleared.append(True)  # type: ignore[method-assign]
    async with app.run_test(size=SIZE) as pilot:
        await _plan_screen(pilot)
        app.screen.query_one("#steps", Input).value = "60"
        await pilot.press("s")
        await settle(pilot)
        assert app.session.plans.plan is not None and app.session.plans.plan.N == 60, status_of(app)
        assert "N = 60" in text_of(app, "#plan-text")
        assert "✔ Plan" in text_of(app, "#steps-line")

        app.screen.query_one("#goal-values", AnglesInput).set_values(goal)
        app.screen.query_one("#method", Select).value = method
        app.screen.query_one("#steps", Input).value = steps
        await pilot.pause()
        await pilot.press("s")
        await settle(pilot, timeout_s=120)

        name = {"mvn": "MVN", "mintime": "minimum-time"}[method]
        assert app.session.plans.plan is None  # nothing left that "execute" could run
        out = text_of(app, "#plan-text")
        # a goal refused with its reason is not a solver's failure
        assert out.startswith(f"No {name} plan:\n"), out
        assert "solve failed" not in out
        assert "N = 60" not in out and "\nNext: " in out
        assert why in out
        assert text_of(app, "#plan-plot") == "no plan"
        assert cleared  # the 3D path preview of the old plan is gone
        status = status_of(app)
        assert status.startswith(f"no {name} plan: {why}"), status
        assert "✔ Plan" not in text_of(app, "#steps-line")


async def test_a_solver_failure_is_told_apart_from_a_refusal(console: Any) -> None:
    """Only a solver that failed reads "the … solve failed" (a refused request gives its
    reason under "No … plan:", see above)."""
    from spm_console.errors import SolverError

    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await _plan_screen(pilot)

        def fail(*_: Any, **__: Any) -> None:
            raise SolverError("the QP solvers failed on the MVN problem (N = 60): a test's reason")

        app.session.plans.solve = fail  # type: ignore[method-assign,assignment]
        await pilot.press("s")
        await settle(pilot)
        out = text_of(app, "#plan-text")
        assert out.startswith("No plan: the MVN solve failed.\n"), out
        assert status_of(app).startswith("MVN solve failed (no plan now): the QP solvers"), \
            status_of(app)


async def test_a_failed_fk_clears_the_previous_result(console: Any) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("2")
        theta = app.screen.query_one("#theta", AnglesInput)
        theta.set_values([95, 110, 105])
        await pilot.press("f")
        await settle(pilot)
        assert "FEASIBLE" in text_of(app, "#fk-result")
        theta.set_values([65, 155, 65])  # crosses a singularity from home: no unique FK
        await pilot.press("f")
        await settle(pilot)
        out = text_of(app, "#fk-result")
        assert out.startswith("No result: FK failed.\nθ = [65.00, 155.00, 65.00]°"), out
        assert "FEASIBLE" not in out and "\nNext: " in out
        assert status_of(app).startswith("FK failed: θ = [65.00, 155.00, 65.00]°"), status_of(app)
        theta.set_values([95, 110, 105])
        await pilot.press("f")
        await settle(pilot)
        assert "FEASIBLE" in text_of(app, "#fk-result")
        theta.query_one(Input).value = "abc"  # refused before anything is computed
        await pilot.press("f")
        await settle(pilot)
        out = text_of(app, "#fk-result")
        assert out.startswith("No result: FK refused.") and "FEASIBLE" not in out, out


async def test_a_failed_check_clears_the_previous_verdict(console: Any) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("3")
        await settle(pilot)
        await pilot.press("k")
        await settle(pilot)
        assert "plannable in P" in text_of(app, "#ws-check")

        def broken(theta: Any) -> Any:
            raise SpmError("the check broke")

        app.session.wrist.check_theta = broken  # type: ignore[method-assign]
        await pilot.press("k")
        await settle(pilot)
        out = text_of(app, "#ws-check")
        assert out.startswith("No verdict: the check failed.\nthe check broke"), out
        assert "plannable" not in out and "\nNext: " in out
        assert status_of(app) == "check failed: the check broke"


async def test_a_failed_rebuild_says_the_loaded_workspace_stays(console: Any) -> None:
    app = console()
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("3")
        await settle(pilot)
        info = text_of(app, "#ws-info")

        def broken(progress: Any = None, force: bool = False) -> Any:
            raise CacheError("disk full")

        app.session.wrist.load_workspace = broken  # type: ignore[method-assign]
        await pilot.press("b", "y")
        await settle(pilot)
        assert status_of(app) == "disk full (the workspace shown, loaded before, stays in use)"
        assert text_of(app, "#ws-info") == info and app.session.wrist.workspace is not None
