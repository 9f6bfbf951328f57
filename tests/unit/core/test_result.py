"""A planner's result as a plan (core.planning.result.PlanResult.to_plan), against the
values the problem and the result were built from here by hand (no solve): what was asked,
the trajectories, the route only when there is more than one region. Angles in degrees,
speeds in deg/s."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from spm_console.core.plan_report import REPORT_NUMBERS, ConstraintReport
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.planning.result import PlanResult
from spm_console.core.polytope.region import Region
from spm_console.core.regions.route import RegionRoute
from spm_console.core.servo.model import discretize

MODEL = discretize(32.22, 0.02)
START = (100.0, 90.0, 80.0)
GOAL = (110.0, 95.0, 70.0)
N = 4
BOX = Region.box(65.0, 155.0)


def _report() -> ConstraintReport:
    values = {name: 1e-3 * (k + 1) for k, name in enumerate(REPORT_NUMBERS)}
    return ConstraintReport(**values, points_per_interval=8, ok=True)


def _result(problem: PlanProblem) -> PlanResult:
    k = np.arange(N + 1)[:, None]
    ref = np.asarray(START) + (np.asarray(GOAL) - np.asarray(START)) * k / N
    return PlanResult("optimal", problem, ref, ref - 0.5, np.full((N + 1, 3), 2.0), cost=60.0,
                      solve_seconds=0.25, qp_count=3, check=_report(),
                      info={"rounds": 2, "rows": 17})


def test_plan_carries_what_was_asked_and_the_trajectories() -> None:
    """Kind, Ts, N and duration, the three trajectories, cost, time, QP count and report as
    given; the options are the problem's, as plain Python floats; no limits, no route; the
    solver details are a copy (a change to the plan's leaves the result's as it was)."""
    pb = PlanProblem(MODEL, np.array(START), np.array(GOAL), N, BOX, vmax_degps=50,
                     intersample=2, hold_first=False)
    res = _result(pb)
    plan = res.to_plan("mintime", profile_hash="abc123")
    assert res.N == N == plan.N
    assert plan.kind == "mintime" and plan.profile_hash == "abc123"
    assert plan.Ts == 0.02 and plan.duration_s == pytest.approx(0.08, abs=1e-12)
    assert plan.reference_deg[2] == pytest.approx([105.0, 92.5, 75.0], abs=1e-12)
    assert plan.position_deg[0] == pytest.approx([99.5, 89.5, 79.5], abs=1e-12)
    assert (plan.velocity_degps == 2.0).all()
    assert (plan.cost, plan.solve_seconds, plan.qp_count) == (60.0, 0.25, 3)
    assert plan.check == _report() and plan.region is BOX and plan.model is MODEL
    o = plan.options
    assert o is not None
    assert o.start_deg == START and o.goal_deg == GOAL
    assert all(type(x) is float for x in (*o.start_deg, *o.goal_deg, o.vmax_degps))
    assert (o.vmax_degps, o.intersample, o.hold_first) == (50.0, 2, False)
    assert o.reference_limits_deg is None
    assert plan.route is None
    assert plan.solver == {"rounds": 2, "rows": 17}
    assert plan.solver is not None
    plan.solver["rounds"] = 99
    assert res.info == {"rounds": 2, "rows": 17}
    unbounded = _result(replace(pb, vmax_degps=None)).to_plan().options
    assert unbounded is not None and unbounded.vmax_degps is None
    assert _result(pb).to_plan().kind == "mvn"


@pytest.mark.parametrize(("lo", "hi"), [((60.0, 61.0, 62.0), None), (None, (160.0, 161.0, 162.0)),
                                        ((60.0, 61.0, 62.0), (160.0, 161.0, 162.0))])
def test_reference_limits_are_given_when_either_bound_is(
        lo: tuple[float, float, float] | None, hi: tuple[float, float, float] | None) -> None:
    """One bound or both: the pair (lower, upper), the missing one None, each bound three
    floats in degrees."""
    pb = PlanProblem(MODEL, np.array(START), np.array(GOAL), N, BOX,
                     ref_lo_deg=None if lo is None else np.array(lo),
                     ref_hi_deg=None if hi is None else np.array(hi))
    o = _result(pb).to_plan().options
    assert o is not None
    assert o.reference_limits_deg == (lo, hi)


def test_route_is_kept_only_across_several_regions() -> None:
    """A two-region route switching at sample 2 is the plan's route; a one-region route is
    none (the plan lies in ``region`` alone)."""
    second = Region.box(60.0, 150.0)
    two = RegionRoute((BOX, second), (2,))
    pb = PlanProblem(MODEL, np.array(START), np.array(GOAL), N, BOX, route=two)
    assert _result(pb).to_plan().route is two
    one = PlanProblem(MODEL, np.array(START), np.array(GOAL), N, BOX,
                      route=RegionRoute.single(BOX, "P"))
    assert _result(one).to_plan().route is None
