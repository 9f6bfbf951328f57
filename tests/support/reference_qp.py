"""Independent reference formulation of (30) in cvxpy: the tests check the planners against
it and the benchmarks use it as their baseline (not shipped in the package).

Written from the paper's equations, not from the OSQP matrices: one (N+1)×3 variable
per quantity, constraints stated as in (30b)–(30f), the sub-sample constraints through
the exact sub-sampled matrices. Solved by Clarabel (interior point) unless told otherwise.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import cvxpy as cp
import numpy as np
from numpy.typing import NDArray

from spm_console.core.planning.problem import PlanProblem, sub_instants, sub_matrices
from spm_console.core.planning.qp_build import PLAN_STEP_DEG

F = NDArray[np.float64]


@dataclass(frozen=True)
class ReferenceSolution:
    """A cvxpy solve of (30)."""

    status: str
    """cvxpy's status string ('optimal', 'infeasible', …)."""
    cost: float
    reference_deg: F | None
    position_deg: F | None
    velocity_degps: F | None
    seconds: float
    """Wall time of defining and solving the problem, s."""
    solver: str


def formulate(pb: PlanProblem) -> tuple[cp.Problem, cp.Variable, cp.Variable, cp.Variable]:
    """(problem, θ, θ̇, θ*) of (30) in cvxpy."""
    N = pb.N
    th = cp.Variable((N + 1, 3))
    om = cp.Variable((N + 1, 3))
    ref = cp.Variable((N + 1, 3))
    A, B = pb.model.A, pb.model.B
    cons = [
        th[0] == pb.start_deg, om[0] == 0, th[N] == pb.goal_deg, om[N] == 0,  # (30b, c)
        ref[N] == pb.goal_deg,
        th[1:] == A[0, 0] * th[:-1] + A[0, 1] * om[:-1] + B[0] * ref[:-1],  # (30f)
        om[1:] == A[1, 0] * th[:-1] + A[1, 1] * om[:-1] + B[1] * ref[:-1],
    ]
    # (30e): sample k inside every region of the intervals it ends or starts (route)
    route = pb.regions
    for i, reg in enumerate(route.regions):
        ks = np.flatnonzero(route.sample_mask(N)[:, i])
        cons.append(th[ks] @ reg.A.T <= np.tile(reg.b, (len(ks), 1)))
    if pb.hold_first:
        cons.append(ref[0] == pb.start_deg)
    # the runtime's largest reference step, from θ(0) (the reference held before) to θ*(N)
    cons.append(cp.abs(ref[0] - pb.start_deg) <= PLAN_STEP_DEG)
    cons.append(cp.abs(ref[1:] - ref[:-1]) <= PLAN_STEP_DEG)
    if pb.vmax_degps is not None:
        cons.append(cp.abs(om) <= pb.vmax_degps)  # (30d)
    if pb.lead_max_deg is not None:  # the servo's linear range: |θ*(k) − θ(k)|, k < N
        cons.append(cp.abs(ref[:N] - th[:N]) <= pb.lead_max_deg)
    if pb.ref_lo_deg is not None:
        cons.append(ref[:N] >= np.tile(pb.ref_lo_deg, (N, 1)))
    if pb.ref_hi_deg is not None:
        cons.append(ref[:N] <= np.tile(pb.ref_hi_deg, (N, 1)))
    Phis, Gams = sub_matrices(pb)
    for j in range(Phis.shape[0]):
        ph, ga = Phis[j], Gams[j]
        ths = ph[0, 0] * th[:-1] + ph[0, 1] * om[:-1] + ga[0] * ref[:-1]
        for i, reg in enumerate(route.regions):
            js = np.flatnonzero(route.interval_mask(N)[:, i])
            cons.append(ths[js] @ reg.A.T <= np.tile(reg.b, (len(js), 1)))
        if pb.vmax_degps is not None:
            oms = ph[1, 0] * th[:-1] + ph[1, 1] * om[:-1] + ga[1] * ref[:-1]
            cons.append(cp.abs(oms) <= pb.vmax_degps)
    # the runtime's check instants: its between-sample speed bound there
    sub = sub_instants(pb)
    for j in np.flatnonzero(~sub.requested) if pb.vmax_degps is not None else ():
        ph, ga = sub.phis[j], sub.gams[j]
        oms = ph[1, 0] * th[:-1] + ph[1, 1] * om[:-1] + ga[1] * ref[:-1]
        cons.append(cp.abs(oms) <= sub.speed_bound_degps[j])
    prob = cp.Problem(cp.Minimize(cp.sum_squares(om)), cons)
    return prob, th, om, ref


def solve_reference(pb: PlanProblem, solver: str | None = "CLARABEL",
                    **options: object) -> ReferenceSolution:
    """Define and solve (30) with cvxpy (``solver=None``: cvxpy's default choice)."""
    t0 = time.perf_counter()
    prob, th, om, ref = formulate(pb)
    kwargs: dict[str, object] = dict(options)
    if solver is not None:
        kwargs["solver"] = solver
    prob.solve(**kwargs)
    dt = time.perf_counter() - t0
    used = prob.solver_stats.solver_name if prob.solver_stats else str(solver)
    if prob.status not in ("optimal", "optimal_inaccurate"):
        return ReferenceSolution(str(prob.status), float("inf"), None, None, None, dt, used)
    return ReferenceSolution(str(prob.status), float(prob.value), np.asarray(ref.value),
                             np.asarray(th.value), np.asarray(om.value), dt, used)
