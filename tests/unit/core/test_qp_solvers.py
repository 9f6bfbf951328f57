"""The planner's QP solvers behind one interface: OSQP, Clarabel and an independent cvxpy
formulation answer the same reduced QP with the same optimum, and every answer's KKT
residuals, computed by the solution itself from the problem's matrices, are small."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from spm_console.core.planning.problem import PlanProblem
from spm_console.core.planning.qp_build import Equalities, Pool, equalities
from spm_console.core.planning.screening import SOLVERS
from spm_console.core.planning.solvers.base import QpSolution, QpSolver
from spm_console.core.planning.solvers.clarabel_qp import ClarabelQp
from spm_console.core.planning.solvers.osqp_qp import OsqpQp
from tests.support.cvxpy_qp import CvxpyQp
from tests.support.planning_cases import GOAL, HARD_CASES, MODEL, START, Case

SOLVER_LIST: list[QpSolver] = [OsqpQp(), ClarabelQp(), CvxpyQp()]


def _problem(c: Case) -> PlanProblem:
    return PlanProblem(MODEL, START, GOAL, c.N, c.region, c.vmax, c.K, **c.limits())


def _screened(pb: PlanProblem) -> tuple[Equalities, Pool, NDArray[np.int64]]:
    """The rows a screening round would choose around the straight guess (a reduced QP of
    the size the solvers see), plus everything binding at the optimum."""
    from spm_console.core.planning.mvn import run_qp, straight_guess

    eq, pool = equalities(pb), Pool(pb)
    _, out = run_qp(pb)
    near = np.flatnonzero(pool.slack(straight_guess(pb)) < 0.5)
    return eq, pool, np.union1d(near, out.active).astype(np.int64)


@pytest.mark.parametrize("case", HARD_CASES[2:5], ids=lambda c: c.name)
def test_every_solver_gives_the_same_optimum_and_small_residuals(case: Case) -> None:
    pb = _problem(case)
    eq, pool, chosen = _screened(pb)
    answers: list[QpSolution] = [s.solve(eq, pool, chosen, None) for s in SOLVER_LIST]
    costs = []
    for sol in answers:
        assert sol.solved, (sol.solver, sol.status, sol.detail)
        assert sol.z is not None
        r = sol.residuals(eq, pool)
        scale = max(1.0, float(np.abs(sol.z).max()))
        tol = 1e-3 if sol.solver == "osqp" and not sol.polished else 1e-5
        assert r.primal <= tol * scale, (sol.solver, r)
        assert r.dual <= 1e-3 * scale, (sol.solver, r)
        cost = 0.5 * float(sol.z @ (eq.P @ sol.z))
        assert r.gap <= 1e-3 * max(1.0, cost), (sol.solver, r)
        costs.append(cost)
    assert max(costs) - min(costs) <= 1e-4 * max(costs)


def test_the_residuals_see_a_wrong_answer() -> None:
    """A point off the optimum, or multipliers of the wrong sign, have large residuals: the
    check measures, it does not echo the solver."""
    pb = _problem(HARD_CASES[3])
    eq, pool, chosen = _screened(pb)
    good = ClarabelQp().solve(eq, pool, chosen)
    assert good.z is not None and good.y_pool is not None and good.y_eq is not None
    r = good.residuals(eq, pool)
    moved = QpSolution("x", "solved", chosen, good.z + 0.5, good.y_eq, good.y_pool)
    assert moved.residuals(eq, pool).primal > 100 * max(r.primal, 1e-9)
    flipped = QpSolution("x", "solved", chosen, good.z, good.y_eq, -good.y_pool)
    assert float(np.abs(good.y_pool).max()) > 0
    assert flipped.residuals(eq, pool).dual > 100 * max(r.dual, 1e-9)
    with pytest.raises(ValueError, match="solved"):
        QpSolution("x", "failed", chosen).residuals(eq, pool)


def test_the_screening_backends_are_these_solvers() -> None:
    assert {k: s.name for k, s in SOLVERS.items()} == {"osqp": "osqp", "clarabel": "clarabel"}
