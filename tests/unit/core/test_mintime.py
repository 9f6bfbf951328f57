"""Minimum time (31): N* feasible, N*−1 infeasible by a checked certificate, cross-checked by cvxpy."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from spm_console.core.planning.mintime import solve_mintime, solve_mintime_problem
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.planning.solvers.clarabel_qp import check_certificate
from spm_console.core.polytope.region import Region
from spm_console.errors import BadInputError, InfeasibleError
from tests.support.planning_cases import GOAL, MODEL, START, START_MT, slab
from tests.support.reference_qp import solve_reference

BOX = Region.box(65.0, 155.0)


def _cross_check(pb: PlanProblem, n: int) -> None:
    """An independent formulation agrees: N feasible, N−1 infeasible."""
    assert solve_reference(pb.with_steps(n)).status == "optimal"
    assert solve_reference(pb.with_steps(n - 1)).status == "infeasible"


@pytest.mark.parametrize(("K", "expected"), [(1, 65), (4, 69)])
def test_paper_experiment_in_the_grid_box(K: int, expected: int) -> None:
    """Paper: [70, 90, 80]° → goal, v_max = 50°/s, reported N = 76 with its (wrong) eq. (35)
    model and its region. Ours (ZOH p = 32.22): joint 2 travels 65° — 1.3 s at 50°/s."""
    res = solve_mintime(MODEL, START_MT, GOAL, BOX, 50.0, intersample=K)
    assert expected == res.N
    assert res.plan.check.ok
    assert res.certificate is not None and res.certificate.valid
    assert res.certificate.excluded_radius >= 1e4
    assert res.qp_count == len(res.trace) and res.qp_count <= 8
    verdicts = {e.N: e.verdict for e in res.trace}
    assert verdicts[expected] == "solved" and verdicts[expected - 1] == "infeasible"
    assert all(v == "infeasible" for n, v in verdicts.items() if n < expected)
    assert all(v == "solved" for n, v in verdicts.items() if n >= expected)
    _cross_check(PlanProblem(MODEL, START_MT, GOAL, 2, BOX, 50.0, K), expected)
    if K == 1:  # the samples obey v_max, the continuous motion slightly exceeds it
        assert res.plan.check.speed_excess_between_degps > 0.5
    else:
        assert res.plan.check.speed_excess_between_degps < 0.1


def test_thin_region_with_reference_limits() -> None:
    region = slab(START, GOAL, 0.1)
    lo, hi = np.full(3, 60.0), np.array([160.0, 155.05, 160.0])
    res = solve_mintime(MODEL, START, GOAL, region, 45.0, ref_lo_deg=lo, ref_hi_deg=hi)
    assert res.plan.check.ok and res.certificate is not None and res.certificate.valid
    _cross_check(PlanProblem(MODEL, START, GOAL, 2, region, 45.0, 1, True, lo, hi), res.N)
    plan = res.to_plan(profile_hash="x")
    assert plan.kind == "mintime" and plan.qp_count == res.qp_count
    rec = plan.certificate
    assert rec is not None and rec.N == res.N - 1
    assert rec.certificate is not None and rec.certificate.valid


def test_certificate_checker_rejects_forgeries() -> None:
    # x ≤ 1 and −x ≤ −2 (x ≥ 2): y = (1, 1) proves it infeasible
    A = sp.csc_matrix(np.array([[1.0], [-1.0]]))
    b = np.array([1.0, -2.0])
    assert check_certificate(A, b, np.array([1.0, 1.0]), 0).valid
    assert not check_certificate(A, b, np.array([1.0, 0.5]), 0).valid  # Aᵀy ≠ 0
    assert not check_certificate(A, b, np.array([-1.0, -1.0]), 0).valid  # bᵀy > 0
    assert not check_certificate(A, np.array([2.0, -1.0]), np.array([1.0, 1.0]), 0).valid


def test_bad_requests() -> None:
    pb = PlanProblem(MODEL, START_MT, GOAL, 2, BOX)
    with pytest.raises(BadInputError, match="v_max"):
        solve_mintime_problem(pb)
    with pytest.raises(InfeasibleError, match="outside the region"):
        solve_mintime(MODEL, START_MT, GOAL, Region.box(80.0, 150.0), 50.0)


def test_an_infeasibility_whose_certificate_does_not_check_out_is_searched_past(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The interior-point solver says N* − 1 is infeasible but its Farkas vector does not
    verify (status 'failed' with a certificate not valid): the search takes it as infeasible,
    finds the same N*, and the plan keeps the certificate as not valid (not proven
    fastest) instead of failing the whole plan."""
    import spm_console.core.planning.mintime as mt

    honest = solve_mintime(MODEL, START_MT, GOAL, BOX, 50.0)
    real = mt._decide

    def shaky(problem: PlanProblem, guess: np.ndarray,  # type: ignore[no-untyped-def]
              expect_feasible: bool):
        out, eq = real(problem, guess, expect_feasible)
        if out.status == "infeasible":
            assert out.certificate is not None
            forged = type(out.certificate)(out.certificate.residual_l1, 1.0, 0.0,
                                           out.certificate.rows, False)
            out = type(out)(**{**out.__dict__, "status": "failed", "certificate": forged,
                               "detail": "AlmostPrimalInfeasible"})
        return out, eq

    monkeypatch.setattr(mt, "_decide", shaky)
    res = solve_mintime(MODEL, START_MT, GOAL, BOX, 50.0)
    assert res.N == honest.N and res.plan.check.ok
    assert res.certificate is not None and not res.certificate.valid


def test_a_lead_limited_speed_is_predicted_without_galloping() -> None:
    """An identified servo (ζ = 0.79) with a 3.57° linear range at 200°/s: the lead, not the
    speed bound, sets N*. The prediction takes the lead's scaling too, so the search decides
    N* and N*−1 only; an independent formulation agrees on both."""
    from spm_console.core.servo.model import Dynamics, discretize

    model = discretize(Dynamics(44.03, 0.786, 0.0053), 0.02)
    lo, hi = np.full(3, 60.0), np.full(3, 160.0)
    pb = PlanProblem(model, START_MT, GOAL, 2, BOX, 200.0, 1, True, lo, hi, lead_max_deg=3.57)
    res = solve_mintime_problem(pb)
    assert res.plan.check.ok and res.certificate is not None and res.certificate.valid
    lead = np.abs(res.plan.reference_deg[:-1] - res.plan.position_deg[:-1]).max()
    assert lead == pytest.approx(3.57, abs=1e-3)  # the lead binds
    assert float(np.abs(res.plan.velocity_degps).max()) < 150.0  # the speed bound does not
    assert res.qp_count <= 3, [(e.N, e.verdict) for e in res.trace]
    _cross_check(pb, res.N)
