"""The dual active-set method on (30) (core/planning/dual_active_set).

Independent references: the screened Clarabel solve and its exact refinement (the planner's
other path) for the optimum and its working set, and cvxpy for an infeasible horizon; the
Farkas certificate is checked by the same check as Clarabel's."""

from __future__ import annotations

from dataclasses import replace

import pytest

from spm_console.core.planning.dual_active_set import dual_active_set
from spm_console.core.planning.mvn import finish, solve_problem, straight_guess
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.planning.qp_build import Pool, equalities
from spm_console.core.planning.screening import solve_qp
from tests.support.planning_cases import GOAL, HARD_CASES, MODEL, START, Case, polytope
from tests.support.reference_qp import solve_reference


def _problem(c: Case) -> PlanProblem:
    return PlanProblem(MODEL, START, GOAL, c.N, c.region, c.vmax, c.K, **c.limits())


@pytest.mark.parametrize("case", HARD_CASES[2:], ids=lambda c: c.name)
def test_it_certifies_what_the_screened_solver_finds(case: Case) -> None:
    """Alone (no QP solver call) it ends at the optimum the screened Clarabel solve and its
    refinement certify (the same cost, the same velocities: the optimum's θ̇ is unique, its
    working set need not be where rows are degenerate), and its point passes the planner's
    checks; started from its own working set it certifies at once, and from the screened
    solver's too."""
    pb = _problem(case)
    eq, pool = equalities(pb), Pool(pb)
    dual = dual_active_set(eq, pool)
    out = solve_qp(eq, pool, straight_guess(pb), backend="clarabel", try_active_set=False)
    screened = finish(pb, eq, out, 0.0)
    assert dual.ok and dual.z is not None and out.certified
    cost = float(dual.z @ (eq.P @ dual.z)) / 2.0
    assert cost == pytest.approx(screened.cost, rel=1e-9)
    mine = finish(pb, eq, replace(out, z=dual.z), 0.0)
    assert mine.check.ok
    assert abs(mine.velocity_degps - screened.velocity_degps).max() <= 1e-6
    for active, side in ((dual.active, dual.side), (out.active, out.side)):
        warm = dual_active_set(eq, pool, active, side)
        assert warm.ok and warm.solves == 0


def test_a_row_no_step_can_meet_gives_a_checked_farkas_certificate() -> None:
    """Too few steps (N = 5, 12, 20) for the speed bound: within its default steps the method
    ends with a row dependent on its working set and a valid certificate, where cvxpy also
    finds the problem infeasible; the planner refuses it as infeasible by that certificate."""
    for n in (5, 12, 20):
        pb = PlanProblem(MODEL, START, GOAL, n, polytope(), 50.0)
        eq, pool = equalities(pb), Pool(pb)
        r = dual_active_set(eq, pool)
        assert not r.ok and r.certificate is not None and r.certificate.valid, n
        assert r.certificate.solver == "dual active set" and r.certificate.cone_violation == 0.0
        assert solve_reference(pb).status == "infeasible"
        out = solve_qp(eq, pool, straight_guess(pb), backend="clarabel")
        assert out.status == "infeasible" and out.certificate == r.certificate


def test_past_its_steps_it_hands_over_and_the_plan_is_the_same(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Cut off after one step it certifies nothing and claims nothing; the planner's QP
    solvers then take over and give the same optimum."""
    import spm_console.core.planning.screening as screening

    pb = _problem(HARD_CASES[4])
    eq, pool = equalities(pb), Pool(pb)
    r = dual_active_set(eq, pool, max_steps=1)
    assert not r.ok and r.certificate is None
    full = dual_active_set(eq, pool)
    assert full.ok and full.z is not None
    monkeypatch.setattr(screening, "dual_active_set",
                        lambda eq, pool, a, s: dual_active_set(eq, pool, a, s, max_steps=1))
    plan = solve_problem(pb)
    assert plan.info["method"] != "active-set" and plan.info["solver_calls"] >= 1
    assert plan.cost == pytest.approx(float(full.z @ (eq.P @ full.z)) / 2.0, rel=1e-9)


@pytest.mark.parametrize(("p", "ts"), [(1.0, 0.001), (43.0, 0.02), (1000.0, 0.02)],
                         ids=["slow", "paper-like", "stiff"])
def test_the_free_optimum_is_the_exact_solution_of_the_equalities(p: float, ts: float) -> None:
    """Minimum time's prediction solves the equalities alone on the kept factorization. It
    must be the exact KKT solution: a dense LU of K₀ (LAPACK's, refined) agrees with it to
    round-off, however badly K₀ is conditioned (a slow or stiff servo's: p·Ts from 1e-3 to
    20, cond(K₀) up to 1e11). It costs no more than the equality-constrained point
    :func:`eqp` finds with no row held (eqp's regularized factor drifts along K₀'s
    near-null directions on the stiff servo: a point that meets the equalities but costs
    up to 20 times the minimum there)."""
    import numpy as np
    import scipy.sparse as sp

    from spm_console.core.planning.active_set import eqp
    from spm_console.core.planning.dual_active_set import free_optimum
    from spm_console.core.servo.model import discretize

    model = discretize(p, ts)
    for N in (3, 7, 40):
        pb = PlanProblem(model, START, GOAL, N, polytope(), hold_first=False)
        eq = equalities(pb)
        K = sp.bmat([[eq.P, eq.C.T], [eq.C, None]]).toarray()
        f = np.concatenate([np.zeros(eq.P.shape[0]), eq.d])
        exact = np.linalg.solve(K, f)
        for _ in range(3):
            exact = exact + np.linalg.solve(K, f - K @ exact)
        z = free_optimum(eq)
        ref = eqp(eq, Pool(pb), np.zeros(0, np.int64), np.zeros(0, np.int64))
        assert ref is not None and z is not None
        scale = max(1.0, float(np.abs(exact).max()))
        assert float(np.abs(z - exact[: z.size]).max()) <= 1e-9 * scale
        cost, eqp_cost = float(z @ (eq.P @ z)), float(ref[0] @ (eq.P @ ref[0]))
        assert cost <= eqp_cost * (1 + 1e-9) + 1e-15
