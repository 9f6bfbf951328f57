"""Every refusal of the planner and the region choice carries its Issue where it is raised:
a front end picks its advice by the Issue, never by searching the message's words."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import pytest

import spm_console.core.planning.mintime as mintime
from spm_console.config.schema import Profile
from spm_console.core.bounds import MAX_INSTANTS
from spm_console.core.planning.mintime import solve_mintime
from spm_console.core.planning.mvn import solve_mvn, solve_problem
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.planning.route_search import RouteChoice, solve_route_mvn
from spm_console.core.polytope.region import Region
from spm_console.core.regions.choice import choose_region
from spm_console.core.regions.route import RegionRoute
from spm_console.core.servo.model import discretize
from spm_console.core.workspace.data import NodeClass
from spm_console.core.workspace.segment_check import check_segment
from spm_console.errors import Issue, SpmError
from spm_console.motion.plan_check import verify_plan
from spm_console.motion.plans import plan_from_references
from spm_console.services.plan_request import PlanRequest, precheck
from tests.support.planning_cases import GOAL, MODEL, START, START_MT, polytope
from tests.support.ws_helpers import agile_workspace

BOX = Region.box(65.0, 155.0)


def _route_too_few() -> None:
    solve_route_mvn(PlanProblem(MODEL, START, GOAL, 2, BOX, 40.0), [BOX, BOX, BOX],
                    RouteChoice((0, 1, 2), np.zeros((4, 3)), 1.0))


#: (what is refused, how, the Issue it carries, words of its message).
CASES: list[tuple[str, Callable[[], object], Issue, str]] = [
    ("mvn-no-reference", lambda: solve_problem(PlanProblem(MODEL, START, GOAL, 60, polytope(), 50.0)),
     Issue.TOO_FEW_STEPS, "no reference reaches the goal in N = 60"),
    ("route-too-few", _route_too_few, Issue.TOO_FEW_STEPS, "too few for a route through 3"),
    ("route-no-room", lambda: PlanProblem(MODEL, START, GOAL, 2, BOX, 40.0,
                                          route=RegionRoute((BOX, BOX, BOX), (1, 2))),
     Issue.TOO_FEW_STEPS, "leave no room for the route's switch samples"),
    ("mintime-too-slow", lambda: solve_mintime(MODEL, START_MT, GOAL, BOX, 0.01),
     Issue.SPEED_TOO_LOW, "use a speed bound of at least"),
    ("too-many-instants", lambda: PlanProblem(MODEL, START, GOAL, 2000, BOX, None, 51),
     Issue.TOO_MANY_INSTANTS, f"above {MAX_INSTANTS:,} constrained instants"),
    ("intersample-range", lambda: PlanProblem(MODEL, START, GOAL, 50, BOX, None, 101),
     Issue.TOO_MANY_INSTANTS, "intersample K must be an integer in 1..100"),
    ("intersample-zoh", lambda: PlanProblem(discretize(32.22, 0.02, "tustin"), START, GOAL, 50,
                                            BOX, None, 3),
     Issue.TOO_MANY_INSTANTS, "intersample constraints need the exact (zoh) servo model"),
    ("below-reference-limits",
     lambda: solve_mvn(MODEL, START, GOAL, 150, polytope(), ref_lo_deg=np.full(3, 70.0)),
     Issue.END_NOT_FEASIBLE, "goal θ = [66.8000, 155.0000, 131.4800]° is below the reference"),
    ("above-reference-limits",
     lambda: solve_mvn(MODEL, START, GOAL, 150, polytope(), ref_hi_deg=np.full(3, 150.0)),
     Issue.END_NOT_FEASIBLE, "is above the reference limits"),
]


@pytest.mark.parametrize(("refuse", "issue", "words"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])
def test_each_planner_refusal_carries_its_issue(refuse: Callable[[], object], issue: Issue,
                                                words: str) -> None:
    with pytest.raises(SpmError) as exc:
        refuse()
    assert exc.value.issue is issue, exc.value.message
    assert words in exc.value.message


def test_the_search_refuses_beyond_its_largest_horizon_with_its_issue(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """No plan within N ≤ n_max: the search's own refusal (the horizon check before it, which
    refuses first in practice, is set aside; this move needs N = 18)."""
    monkeypatch.setattr(mintime, "horizon_limit", lambda problem: 12)
    monkeypatch.setattr(mintime, "_check_horizon", lambda problem, n_max: None)
    with pytest.raises(SpmError) as exc:
        solve_mintime(MODEL, START_MT, GOAL, BOX, 200.0)
    assert exc.value.issue is Issue.NO_PLAN_WITHIN_N_MAX
    assert "no feasible plan with N ≤ 12 steps" in exc.value.message


def test_the_services_precheck_keeps_the_planners_issue(agile: Profile) -> None:
    with pytest.raises(SpmError) as exc:
        precheck(agile, PlanRequest("mintime", np.full(3, 135.0), np.full(3, 95.0),
                                    vmax_degps=0.01))
    assert exc.value.issue is Issue.SPEED_TOO_LOW


def test_region_and_segment_refusals_say_an_end_is_not_feasible(agile: Profile) -> None:
    ws = agile_workspace()
    s, g = np.array([121.0, 65.0, 87.0]), np.array([139.0, 67.0, 107.0])
    with pytest.raises(SpmError) as seg:  # the grid's P′ does not hold the straight segment
        check_segment(ws, s, g)
    assert seg.value.issue is Issue.END_NOT_FEASIBLE
    assert "straight segment" in seg.value.message
    empty = dataclasses.replace(ws, klass=np.full_like(ws.klass, NodeClass.SINGULAR))
    with pytest.raises(SpmError) as none:
        choose_region(empty, s, g)
    assert none.value.issue is Issue.END_NOT_FEASIBLE
    assert "the workspace has no feasible node" in none.value.message
    top = agile.bus.joints[1].max_deg
    ref = np.tile([100.0, top - 0.1, 100.0], (30, 1))
    ref[5:, 1] = top + 0.05
    with pytest.raises(SpmError) as limits:  # the runtime's verification the planner ends with
        verify_plan(agile, ws, plan_from_references(agile, ref, "synthetic"))
    assert limits.value.issue is Issue.END_NOT_FEASIBLE
    assert "outside the servo limits" in limits.value.message
