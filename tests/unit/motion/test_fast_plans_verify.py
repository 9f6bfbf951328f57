"""Fast minimum-time plans are plans the runtime accepts: the QP holds the runtime's largest
reference step (a rule the planner did not know: at 150 and 200 °/s it returned references
jumping 13.8° and 17.9° in one sample, which its own verification then refused)."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.config.models import servo_limits_deg, servo_model_of
from spm_console.core.plan_rules import MAX_REFERENCE_STEP_DEG
from spm_console.core.planning.mintime import solve_mintime
from spm_console.core.regions.choice import choose_region
from spm_console.motion.plan_check import verify_plan
from tests.support.planning_cases import GOAL, MODEL, START_MT
from tests.support.reference_qp import solve_reference
from tests.support.ws_helpers import agile_profile, agile_workspace


@pytest.mark.parametrize("vmax", [100.0, 150.0, 200.0, 270.0])
def test_minimum_time_at_any_rated_speed_passes_the_runtimes_verification(vmax: float) -> None:
    profile = agile_profile()
    fast = profile.model_copy(update={"limits": profile.limits.model_copy(
        update={"vmax_degps": 270.0})})
    ws = agile_workspace()
    region = choose_region(ws, START_MT, GOAL).region
    lo, hi = servo_limits_deg(profile)  # as the command line and the console plan
    res = solve_mintime(servo_model_of(profile), START_MT, GOAL, region, vmax,
                        ref_lo_deg=lo, ref_hi_deg=hi)
    plan = res.to_plan("mintime", profile.digest())
    ref = np.vstack([START_MT[None], plan.reference_deg])
    assert np.abs(np.diff(ref, axis=0)).max() <= MAX_REFERENCE_STEP_DEG + 1e-6
    check = verify_plan(fast, ws, plan)  # raises PlanRefusedError when the runtime refuses
    assert check.points > 0


def test_the_step_bound_is_what_makes_200_degps_slower_and_a_second_solver_agrees() -> None:
    """At 200 °/s in a box the step bound binds: N* is where the cvxpy formulation of (30)
    with the same bound turns feasible."""
    from spm_console.core.polytope.region import Region

    box = Region.box(65.0, 155.0)
    res = solve_mintime(MODEL, START_MT, GOAL, box, 200.0)
    steps = np.abs(np.diff(np.vstack([START_MT[None], res.plan.reference_deg]), axis=0))
    assert steps.max() == pytest.approx(MAX_REFERENCE_STEP_DEG, abs=1e-3)  # it binds
    pb = res.plan.problem
    assert solve_reference(pb.with_steps(res.N)).status == "optimal"
    assert solve_reference(pb.with_steps(res.N - 1)).status == "infeasible"
