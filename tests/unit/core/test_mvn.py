"""MVN (30): optimal against an independent cvxpy + Clarabel formulation, constraints to 1e-6."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.core.planning.mvn import finish, solve_mvn, solve_problem, straight_guess
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.planning.qp_build import Pool, equalities
from spm_console.core.planning.result import PlanResult
from spm_console.core.planning.screening import Backend, QpOutcome, solve_qp
from spm_console.core.polytope.region import Region
from spm_console.core.servo.model import discretize
from spm_console.errors import BadInputError, InfeasibleError
from tests.support.planning_cases import GOAL, HARD_CASES, MODEL, START, Case, polytope, slab
from tests.support.reference_qp import solve_reference

TOL = 1e-6


def _problem(c: Case) -> PlanProblem:
    return PlanProblem(MODEL, START, GOAL, c.N, c.region, c.vmax, c.K, **c.limits())


@pytest.mark.parametrize("case", HARD_CASES, ids=lambda c: c.name)
def test_matches_clarabel_reference(case: Case) -> None:
    pb = _problem(case)
    res = solve_problem(pb)
    ref = solve_reference(pb)
    assert ref.status == "optimal"
    assert abs(res.cost - ref.cost) <= 1e-4 * ref.cost
    assert res.check.ok
    c = res.check
    assert max(c.goal_error_deg, c.final_speed_degps, c.region_violation_deg,
               c.speed_excess_degps, c.reference_excess_deg, c.intersample_violation) <= TOL
    # the plan's own numbers: θ*(N) = goal, θ*(0) = θ(0) (30b as printed), rest at the end
    assert res.reference_deg[-1] == pytest.approx(GOAL, abs=1e-12)
    assert res.reference_deg[0] == pytest.approx(START, abs=TOL)
    assert res.position_deg[-1] == pytest.approx(GOAL, abs=TOL)
    assert res.cost == pytest.approx(float((res.velocity_degps**2).sum()))


def test_hard_cases_really_bind() -> None:
    """The suite is only worth something if constraints are active at the optimum."""
    from spm_console.core.planning.mvn import run_qp

    fams = set()
    for case in HARD_CASES[2:]:
        pb = _problem(case)
        _, out = run_qp(pb)
        pool = Pool(pb)
        fams |= set(pool.family[out.active].tolist())
        assert out.active.size > 0, case.name
    assert {0, 1, 4} <= fams  # region at samples, region between samples, reference bounds


def _screened(pb: PlanProblem, backend: Backend) -> tuple[QpOutcome, PlanResult]:
    """The screened QP solver alone (no dual active set first), then its exact refinement."""
    eq, pool = equalities(pb), Pool(pb)
    out = solve_qp(eq, pool, straight_guess(pb), backend=backend, try_active_set=False)
    return out, finish(pb, eq, out, 0.0)


def test_osqp_backend_agrees() -> None:
    """OSQP on the screened QP (the planner's fallback when the dual active set does not
    certify) gives the optimum Clarabel's gives, its active set certified by refinement."""
    pb = _problem(HARD_CASES[2])
    out_a, a = _screened(pb, "clarabel")
    out_b, b = _screened(pb, "osqp")
    assert out_a.solver_calls >= 1 and out_b.solver_calls >= 1
    assert out_b.certified and out_b.active.size > 0 and b.check.ok
    assert b.cost == pytest.approx(a.cost, rel=1e-6)
    assert np.abs(b.reference_deg - a.reference_deg).max() < 1e-3


def test_between_samples_reported_and_intersample_enforced() -> None:
    region = polytope()
    plain = solve_mvn(MODEL, START, GOAL, 150, region)
    c = plain.check
    # MVN holds θ̇ constant at the samples; the continuous motion ripples above it
    assert c.max_speed_between_degps > c.max_speed_samples_degps + 0.5
    assert c.points_per_interval >= 10
    # a bound between the two is met at the samples but not between them ...
    v = 0.5 * (c.max_speed_samples_degps + c.max_speed_between_degps) + 0.3
    at_samples = solve_mvn(MODEL, START, GOAL, 150, region, vmax=v)
    assert at_samples.check.ok and at_samples.check.speed_excess_between_degps > 0.05
    # ... with K = 5 sub-samples the same N is (certified) infeasible: the ripple cannot
    # go below v while the mean speed is that high ...
    pb = PlanProblem(MODEL, START, GOAL, 150, region, v, 5)
    with pytest.raises(InfeasibleError):
        solve_problem(pb)
    assert solve_reference(pb).status == "infeasible"
    # ... and a few more steps meet the bound at the sub-samples and in between
    sub = solve_mvn(MODEL, START, GOAL, 155, region, vmax=v, intersample=5)
    assert sub.check.ok and sub.check.intersample_violation <= TOL
    assert sub.check.max_speed_between_degps <= v + 1e-6


def test_free_first_reference_is_cheaper_or_equal() -> None:
    region = polytope()
    held = solve_mvn(MODEL, START, GOAL, 100, region)
    free = solve_mvn(MODEL, START, GOAL, 100, region, hold_first=False)
    assert free.cost <= held.cost + 1e-6
    assert not np.allclose(free.reference_deg[0], START)


def test_infeasible_horizon_is_refused_with_the_reason() -> None:
    pb = PlanProblem(MODEL, START, GOAL, 60, polytope(), 50.0)
    with pytest.raises(InfeasibleError, match="N = 60"):
        solve_problem(pb)
    assert solve_reference(pb).status == "infeasible"


def test_endpoints_outside_the_region_are_refused() -> None:
    small = Region.box(80.0, 150.0)
    with pytest.raises(InfeasibleError, match=r"start .* outside the region P"):
        solve_mvn(MODEL, START, GOAL, 150, Region.box(90.0, 160.0))
    with pytest.raises(InfeasibleError, match="outside the region P"):
        solve_mvn(MODEL, START, GOAL, 150, small)
    with pytest.raises(InfeasibleError, match="reference limits"):
        solve_mvn(MODEL, START, GOAL, 150, polytope(), ref_hi_deg=np.full(3, 150.0))


def test_bad_parameters() -> None:
    region = slab(START, GOAL, 1.0)
    with pytest.raises(BadInputError, match="N must be"):
        solve_mvn(MODEL, START, GOAL, 1, region)
    with pytest.raises(BadInputError, match="vmax"):
        solve_mvn(MODEL, START, GOAL, 50, region, vmax=-1.0)
    with pytest.raises(BadInputError, match="intersample"):
        solve_mvn(MODEL, START, GOAL, 50, region, intersample=0)
    with pytest.raises(BadInputError, match="zoh"):
        solve_mvn(discretize(32.22, 0.02, "tustin"), START, GOAL, 50, region, intersample=3)
    with pytest.raises(BadInputError, match="finite"):
        solve_mvn(MODEL, np.array([1.0, np.nan, 2.0]), GOAL, 50, region)


def test_tustin_model_plans_and_reports_the_true_motion() -> None:
    m = discretize(32.22, 0.02, "tustin")
    res = solve_mvn(m, START, GOAL, 150, polytope())
    ref = solve_reference(PlanProblem(m, START, GOAL, 150, polytope()))
    assert abs(res.cost - ref.cost) <= 1e-4 * ref.cost
    assert res.check.ok
