"""Plans for an identified servo (ωn, ζ, a delay, a linear range and a residual bound): the
planner holds the reference's lead within the linear range, the runtime refuses a plan that
does not, plans stay in the tube, and every plan returned passes the runtime's verification up
to the rated 270 °/s. A second solver (cvxpy) with the same constraints agrees on N*."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from spm_console.config.models import servo_limits_deg, servo_model_of
from spm_console.config.schema import Profile
from spm_console.core.planning.mintime import solve_mintime, solve_mintime_problem
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.polytope.region import Region
from spm_console.errors import PlanRefusedError, SolverError
from spm_console.motion.plan_check import verify_plan
from spm_console.services.plan_request import PlanRequest, plan_motion
from tests.support.planning_cases import GOAL, START_MT
from tests.support.reference_qp import solve_reference
from tests.support.ws_helpers import agile_profile, agile_workspace

LEAD_DEG = 6.0
RESIDUAL_DEG = 0.3


def identified(vmax: float = 270.0) -> Profile:
    p = agile_profile()
    servo = p.servo.model_copy(update={"p": 43.0, "zeta": 0.89, "delay_s": 0.0035,
                                       "linear_range_deg": LEAD_DEG,
                                       "residual_bound_deg": RESIDUAL_DEG})
    return p.model_copy(update={"servo": servo, "limits": p.limits.model_copy(
        update={"vmax_degps": vmax})})


def _lead(plan) -> float:  # type: ignore[no-untyped-def]
    return float(np.abs(plan.reference_deg[:-1] - plan.position_deg[:-1]).max())


@pytest.mark.parametrize("vmax", [50.0, 150.0, 270.0])
def test_every_minimum_time_plan_keeps_the_lead_and_passes_the_runtime(vmax: float) -> None:
    prof = identified()
    ws = agile_workspace()
    got = plan_motion(prof, ws, PlanRequest("mintime", START_MT, GOAL, vmax_degps=vmax))
    plan = got.plan
    assert _lead(plan) <= LEAD_DEG + 1e-6
    assert verify_plan(prof, ws, plan).points > 0
    assert plan.model.zeta == 0.89 and plan.model.delay_s == 0.0035
    # the tube: the model's motion keeps the residual bound from every face of P's region
    # except where the goal itself lies nearer (it is on θ2 = 155°)
    if got.region is not None:
        base = got.region.region
        assert base.halfspaces == plan.region.halfspaces
        n = np.linalg.norm(base.A, axis=1)
        moved = (base.b - plan.region.b) / n
        assert moved.max() == pytest.approx(RESIDUAL_DEG) and moved.min() >= 0.0


def test_the_lead_binds_at_speed_and_a_second_solver_agrees_on_the_horizon() -> None:
    model = servo_model_of(identified())
    free = solve_mintime(model, START_MT, GOAL, Region.box(65.0, 155.0), 270.0)
    held = replace(free.plan.problem, lead_max_deg=LEAD_DEG)
    bound = solve_mintime_problem(held)
    assert _lead(free.to_plan("mintime", "")) > LEAD_DEG  # unbounded, the lead is larger
    lead = np.abs(bound.plan.reference_deg[:-1] - bound.plan.position_deg[:-1]).max()
    assert lead == pytest.approx(LEAD_DEG, abs=1e-3)  # it binds
    assert bound.N > free.N
    assert solve_reference(held.with_steps(bound.N)).status == "optimal"
    assert solve_reference(held.with_steps(bound.N - 1)).status == "infeasible"


def test_the_runtime_refuses_a_plan_beyond_the_linear_range() -> None:
    prof = identified()
    ws = agile_workspace()
    lo, hi = servo_limits_deg(prof)
    res = solve_mintime(servo_model_of(prof), START_MT, GOAL, Region.box(65.0, 155.0), 270.0,
                        ref_lo_deg=lo, ref_hi_deg=hi)
    plan = res.to_plan("mintime", prof.digest())
    assert _lead(plan) > LEAD_DEG
    with pytest.raises(PlanRefusedError, match="linear range"):
        verify_plan(prof, ws, plan)


def test_an_underdamped_servo_gets_a_minimum_time_plan_the_runtime_accepts_at_once() -> None:
    """The model identified on the physical wrist at the default speed bound (ωn 44 rad/s,
    ζ 0.79, 5.3 ms, linear range 3.57°): bounded at the samples only (the problem (30) as
    printed), the paper's minimum-time plan at 50 °/s peaks between samples above the
    runtime's 10 % allowance (55.1°/s), and the runtime refuses it. The planner also holds
    the runtime's check instants, so the plan it returns, solved once at K = 1, executes."""
    p = agile_profile()
    prof = p.model_copy(update={"servo": p.servo.model_copy(update={
        "p": 44.03, "zeta": 0.786, "delay_s": 0.0053, "linear_range_deg": 3.57,
        "residual_bound_deg": 0.19})})
    ws = agile_workspace()
    req = PlanRequest("mintime", START_MT, GOAL, vmax_degps=50.0)
    got = plan_motion(prof, ws, req)
    assert got.plan.options is not None and got.plan.options.intersample == 1
    assert got.plan.check is not None and got.plan.check.ok and got.plan.check.runtime_rule == ""
    assert verify_plan(prof, ws, got.plan).points > 0
    # the same problem without the runtime's instants: its optimum breaks the between rule,
    # and the planner's own verdict (the runtime's rules) refuses to return it
    lo, hi = servo_limits_deg(prof)
    route = got.plan.regions  # the regions the plan was solved in, in order
    pb = PlanProblem(servo_model_of(prof), START_MT, GOAL, got.plan.N, route.regions[0], 50.0, 1,
                     True, lo, hi, route=route if route.count > 1 else None, lead_max_deg=3.57,
                     check_points=1)
    with pytest.raises(SolverError, match="runtime's rules: speed above the bound between"):
        solve_mintime_problem(pb)  # its report carries the runtime's verdict: never returned
