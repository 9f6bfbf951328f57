"""Minimum-velocity-norm references, eq. (30), solved by OSQP with screening."""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

from spm_console.core.planning.active_set import WorkingSet
from spm_console.core.planning.problem import Layout, PlanProblem
from spm_console.core.planning.qp_build import Equalities, Pool, equalities
from spm_console.core.planning.result import PlanResult
from spm_console.core.planning.screening import Backend, QpOutcome, solve_qp
from spm_console.core.planning.verify import check
from spm_console.core.polytope.region import Region
from spm_console.core.servo.model import ServoModel
from spm_console.errors import InfeasibleError, Issue, SolverError

F = NDArray[np.float64]

#: A reference beyond a servo limit by at most this much is solver round-off (deg).
ROUND_OFF_DEG = 1e-6


def straight_guess(problem: PlanProblem) -> F:
    """A z vector moving along the straight segment at constant speed (screening guess)."""
    N = problem.N
    L = Layout(N)
    s, g = problem.start_deg, problem.goal_deg
    frac = np.arange(N + 1)[:, None] / N
    th = s + (g - s) * frac
    om = np.tile((g - s) / (N * problem.model.ts), (N + 1, 1))
    om[0] = om[-1] = 0.0
    return L.pack(th, th, om)


def run_qp(problem: PlanProblem, guess: F | None = None,
           backend: Backend = "clarabel",
           warm: WorkingSet | None = None,
           pool: Pool | None = None,
           eq: Equalities | None = None) -> tuple[Equalities, QpOutcome]:
    """Build and solve the QP of ``problem`` (after checking start and goal are in P).

    ``warm``, the working set of a neighbouring problem with the same pool, starts the
    dual active set (its rows with an infinite bound here are left out). ``backend`` solves
    the screened QP when the dual active set does not certify (Clarabel by default: measured
    faster and more robust than OSQP here, see benchmarks/bench_plan.py); if it fails the
    other backend is tried. ``pool``: the problem's own, when the caller has it. ``eq``: its
    equalities, given by a caller that checked its ends (a route's switch candidates share
    the start, goal, N and end regions of the assignment first solved).
    """
    if eq is None:
        problem.check_endpoints()
        eq = equalities(problem)
    if pool is None:
        pool = Pool(problem)
    g = straight_guess(problem) if guess is None else guess
    ws = warm.usable(pool) if warm is not None else None
    out = solve_qp(eq, pool, g, None if ws is None else ws.rows, None if ws is None else ws.side,
                   backend=backend)
    if out.status == "failed" or (out.status == "solved" and not out.certified):
        first = out
        other: Backend = "osqp" if backend == "clarabel" else "clarabel"
        second = solve_qp(eq, pool, g, backend=other, try_active_set=False)
        if second.status == "solved" or first.status == "failed":
            out = second
        out.solver_calls += first.solver_calls
        out.kkt_solves += first.kkt_solves
        out.seconds += first.seconds
    return eq, out


def clamp_round_off(problem: PlanProblem, ref: F) -> F:
    """References that pass a servo limit by round-off only (≤ ROUND_OFF_DEG) set to the limit.

    Solvers meet an active bound θ* ≤ 160° only to their tolerance (160.0000000000051);
    the executor refuses any reference beyond the servo limits, so such a reference is
    put exactly on the limit. A larger excess is left for :func:`check` to report.
    """
    out = ref.copy()
    for bound, sign in ((problem.ref_hi_deg, 1.0), (problem.ref_lo_deg, -1.0)):
        if bound is None:
            continue
        excess = sign * (out - bound)
        near = (excess > 0) & (excess <= ROUND_OFF_DEG)
        out = np.where(near, np.broadcast_to(bound, out.shape), out)
    return out


def finish(problem: PlanProblem, eq: Equalities, out: QpOutcome, t0: float,
           qp_extra: int = 0) -> PlanResult:
    """Turn a solved QP into a verified :class:`PlanResult` (raises if it does not verify)."""
    assert out.z is not None
    ref, pos_z, vel_z = eq.layout.unpack(out.z, problem.goal_deg)
    ref = clamp_round_off(problem, ref)
    if problem.hold_first and float(np.abs(ref[0] - problem.start_deg).max()) <= ROUND_OFF_DEG:
        ref[0] = problem.start_deg  # θ*(0) = θ(0), met by the solver to round-off: exactly
    report, pos, vel = check(problem, ref, pos_z, vel_z)
    if not report.ok:
        raise SolverError(
            f"the solution does not satisfy its constraints to 1e-6 (goal error "
            f"{report.goal_error_deg:.2e}°, region {report.region_violation_deg:.2e}°, speed "
            f"{report.speed_excess_degps:.2e}°/s"
            + (f"; the runtime's rules: {report.runtime_rule}" if report.runtime_rule else "")
            + f"); method {out.method}")
    info = out.info()
    working = WorkingSet(out.active, out.side) if out.certified else None
    return PlanResult("optimal", problem, ref, pos, vel, float((vel**2).sum()),
                      time.perf_counter() - t0, out.qp_count + qp_extra, report, info, working)


def solve_problem(problem: PlanProblem, guess: F | None = None,
                  backend: Backend = "clarabel", warm: WorkingSet | None = None) -> PlanResult:
    """Solve (30) for ``problem``; raises InfeasibleError / SolverError with the reason.
    ``warm``: see :func:`run_qp`."""
    t0 = time.perf_counter()
    eq, out = solved_qp(problem, guess, backend, warm)
    return finish(problem, eq, out, t0)


def solved_qp(problem: PlanProblem, guess: F | None = None, backend: Backend = "clarabel",
              warm: WorkingSet | None = None, pool: Pool | None = None) -> tuple[Equalities, QpOutcome]:
    """:func:`run_qp`, raising InfeasibleError / SolverError unless it solved (the QP's
    answer, before :func:`finish` simulates and verifies it)."""
    eq, out = run_qp(problem, guess, backend, warm, pool)
    if out.status == "infeasible":
        extra = f" under v_max = {problem.vmax_degps}°/s" if problem.vmax_degps else ""
        raise InfeasibleError(
            f"no reference reaches the goal in N = {problem.N} steps ({problem.N * problem.model.ts:g} s)"
            f"{extra} inside the region (infeasibility certified); use more steps or 'plan mintime'",
            Issue.TOO_FEW_STEPS)
    if out.status != "solved":
        raise SolverError(f"the QP solvers failed on the MVN problem (N = {problem.N}): "
                          f"{out.status} {out.detail}")
    return eq, out


def solve_mvn(model: ServoModel, start_deg: F, goal_deg: F, N: int, region: Region,
              vmax: float | None = None, intersample: int = 1, hold_first: bool = True,
              ref_lo_deg: F | None = None, ref_hi_deg: F | None = None) -> PlanResult:
    """Minimum-velocity-norm references (30) from ``start_deg`` to ``goal_deg`` in N steps.

    Angles in degrees, ``vmax`` in deg/s (None: no speed bound), ``intersample`` K ≥ 1
    also enforces (30d, e) at K−1 instants inside every interval.
    """
    pb = PlanProblem(model, np.asarray(start_deg, float), np.asarray(goal_deg, float), N, region,
                     vmax, intersample, hold_first, ref_lo_deg, ref_hi_deg)
    return solve_problem(pb)
