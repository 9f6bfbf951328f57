"""Minimum-time references, eq. (31): the smallest N for which (30) is feasible.

Feasibility is monotone in N (a feasible plan stays feasible with one more rest
sample at the start), so a search over N finds N*. Each N is decided by the
screened solve of (30) (with the MVN cost, so the plan at N* is also the
minimum-velocity-norm one among the fastest): an exact active-set certificate or
Clarabel's solution for *feasible*, a checked interior-point Farkas certificate
for *infeasible*. The search starts from a prediction rather than plain bisection: two exact
solves of the unconstrained MVN problem (around N ≈ (d_max / v_max + 2/p) / Ts)
give the N where its peak speed meets v_max (:func:`predict_steps`); the search
steps by one around it, galloping and bisecting only when the prediction is off.
The answer certifies N* feasible (constraints verified to 1e-6 on the simulated
model) and N*−1 infeasible (certificate).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.core.bounds import MAX_INSTANTS, N_MAX
from spm_console.core.plan import Plan
from spm_console.core.plan_report import Certificate, InfeasibilityRecord, SearchStep
from spm_console.core.planning.dual_active_set import free_optimum
from spm_console.core.planning.mvn import finish, straight_guess
from spm_console.core.planning.problem import Layout, PlanProblem
from spm_console.core.planning.qp_build import Pool, equalities
from spm_console.core.planning.result import PlanResult
from spm_console.core.planning.screening import QpOutcome, solve_qp
from spm_console.core.polytope.region import Region
from spm_console.core.servo.model import ServoModel
from spm_console.errors import BadInputError, InfeasibleError, Issue, SolverError

F = NDArray[np.float64]


@dataclass(frozen=True)
class MintimeResult:
    """Minimum-time plan with its optimality certificate."""

    status: str
    """'optimal' (N* feasible, N*−1 certified infeasible)."""
    plan: PlanResult
    """The MVN-optimal plan at N*."""
    N: int
    certificate: Certificate | None
    """Farkas certificate that N*−1 is infeasible (None when N* is the smallest possible N)."""
    qp_count: int
    """Problems (30) solved (one per N examined)."""
    solver_calls: int
    """Calls of the QP solver (Clarabel) inside them; KKT-only solves are not counted."""
    solve_seconds: float
    trace: list[SearchStep] = field(default_factory=list)
    """Every N examined: verdict, method, seconds."""

    def to_plan(self, kind: Literal["mintime"] = "mintime", profile_hash: str = "") -> Plan:
        """The plan at N* with the search and the N*−1 certificate recorded."""
        plan = self.plan.to_plan(kind, profile_hash)
        return replace(plan, solve_seconds=self.solve_seconds, qp_count=self.qp_count,
                       certificate=self.record())

    def record(self) -> InfeasibilityRecord:
        """What a plan keeps about N*−1 (across regions: for its route only)."""
        route = self.plan.problem.route
        scope = "" if route is None or route.count == 1 else (
            f"for this sequence of {route.count} regions with its switch samples placed in "
            "proportion to the route's length (not a claim about other sequences)")
        return InfeasibilityRecord(N=self.N - 1, certificate=self.certificate,
                                   search=tuple(self.trace), search_seconds=self.solve_seconds,
                                   scope=scope)


def estimate_steps(problem: PlanProblem) -> int:
    """N ≈ (largest joint move / v_max + 2/p) / Ts (+1 with θ*(0) held)."""
    assert problem.vmax_degps is not None
    d = float(np.abs(problem.goal_deg - problem.start_deg).max())
    t = d / problem.vmax_degps + 2.0 / problem.model.dynamics.slowest_rate
    return max(2, math.ceil(t / problem.model.ts) + (1 if problem.hold_first else 0))


def _peaks(problem: PlanProblem) -> tuple[float, float]:
    """(largest |θ̇| at the samples and sub-samples, largest lead |θ*(k) − θ(k)|) of the
    unconstrained MVN optimum at this N, deg/s and deg."""
    eq = equalities(problem)
    z = free_optimum(eq)
    if z is None:
        return float("nan"), float("nan")
    N = problem.N
    x = z[: 6 * (N + 1)].reshape(N + 1, 6)
    peak = float(np.abs(x[:, 3:]).max())
    if problem.intersample > 1:  # the runtime's check instants have a looser bound
        pool = Pool(problem)
        sub = pool.requested_speed_rows()
        if sub.any():
            peak = max(peak, float(np.abs(pool.values(z)[sub]).max()))
    lead = float(np.abs(z[6 * (N + 1):].reshape(N, 3) - x[:N, :3]).max())
    return peak, lead


def predict_steps(problem: PlanProblem, n1: int, gap: int = 6) -> int:
    """Where the unconstrained MVN optimum's peak speed meets v_max, or its peak lead the
    servo's linear range, whichever is later.

    The peak speed behaves like α / (N − c) (a fixed distance over the cruise time), so
    1/peak is nearly linear in N: two probes at n1 and n1 + gap give the line. The lead
    (an acceleration: distance over time squared) behaves like β / (N − c)², so
    1/√lead is nearly linear too. At that N the MVN optimum usually has no active
    constraint, so the prediction is most often N* or close to it.
    """
    assert problem.vmax_degps is not None
    n1 = max(n1, problem.min_steps)
    v1, l1 = _peaks(problem.with_steps(n1))
    v2, l2 = _peaks(problem.with_steps(n1 + gap))
    if not (np.isfinite(v1) and np.isfinite(v2) and v1 > v2 > 0):
        return n1
    slope = (1 / v2 - 1 / v1) / gap
    n = n1 + (1 / problem.vmax_degps - 1 / v1) / slope
    L = problem.lead_max_deg
    if L is not None and np.isfinite(L) and l1 > l2 > 0 and l1 > L:
        y1, y2 = 1 / math.sqrt(l1), 1 / math.sqrt(l2)
        n = max(n, n1 + (1 / math.sqrt(L) - y1) / ((y2 - y1) / gap))
    return max(2, math.ceil(n - 1e-9))


def rescaled_guess(prev: PlanResult, n: int) -> F:
    """The plan ``prev`` stretched or squeezed in time to N = n (a screening guess)."""
    n0 = prev.N
    t_old = np.arange(n0 + 1) / n0
    t_new = np.arange(n + 1) / n
    th = np.column_stack([np.interp(t_new, t_old, prev.position_deg[:, i]) for i in range(3)])
    om = np.column_stack([np.interp(t_new, t_old, prev.velocity_degps[:, i]) for i in range(3)])
    om *= n0 / n
    u = np.column_stack([np.interp(t_new, t_old, prev.reference_deg[:, i]) for i in range(3)])
    return Layout(n).pack(u, th, om)


def horizon_limit(problem: PlanProblem) -> int:
    """Largest N the search may try: N_MAX, fewer with intersample points (N·K ≤ MAX_INSTANTS)."""
    return min(N_MAX, MAX_INSTANTS // problem.intersample)


def _check_horizon(problem: PlanProblem, n_max: int) -> None:
    assert problem.vmax_degps is not None
    check_horizon(problem.model, problem.start_deg, problem.goal_deg, problem.vmax_degps, n_max)


def check_horizon(model: ServoModel, start_deg: F, goal_deg: F, vmax_degps: float,
                  n_max: int) -> None:
    """InfeasibleError at once when even the estimate of N (:func:`estimate_steps`, computed
    in floating point so any v_max > 0 is fine) is beyond the horizon limit ``n_max`` — a
    check that needs no region and no workspace."""
    d = float(np.abs(np.asarray(goal_deg, float) - np.asarray(start_deg, float)).max())
    ts = model.ts
    t = d / vmax_degps + 2.0 / model.dynamics.slowest_rate
    if t / ts <= n_max:
        return
    t_room = max(n_max * ts - 2.0 / model.dynamics.slowest_rate, ts)
    raise InfeasibleError(
        f"no plan within N ≤ {n_max} steps ({n_max * ts:g} s): at v_max = "
        f"{vmax_degps:g} deg/s the largest joint move ({d:.4g}°) needs about "
        f"{t:.3g} s; use a speed bound of at least about {d / t_room:.3g} deg/s",
        Issue.SPEED_TOO_LOW)


def _decide(problem: PlanProblem, guess: F, expect_feasible: bool) -> tuple[QpOutcome, Any]:
    """Solve one N's QP. Where it is expected infeasible (below an N found feasible) the
    screened Clarabel solve goes first: its certificate decides at once, where the dual active
    set would first hold a row for each constraint the optimum would need."""
    eq = equalities(problem)
    pool = Pool(problem)
    return solve_qp(eq, pool, guess, backend="clarabel", try_active_set=expect_feasible), eq


def solve_mintime_problem(problem: PlanProblem) -> MintimeResult:
    """Minimum-time plan for ``problem`` (its N is ignored; v_max is required)."""
    if problem.vmax_degps is None:
        raise BadInputError("minimum time needs a speed bound v_max (deg/s)")
    t0 = time.perf_counter()
    problem.check_endpoints()
    lo_inf: int | None = None  # largest N known infeasible
    hi_feas: int | None = None  # smallest N known feasible
    best: PlanResult | None = None
    cert: Certificate | None = None
    trace: list[SearchStep] = []
    calls = 0
    floor = problem.min_steps
    n_max = horizon_limit(problem)
    _check_horizon(problem, n_max)
    est = estimate_steps(problem)
    n = max(floor, min(predict_steps(problem, min(est, n_max - 6)), n_max))  # probes n1, n1 + 6
    step = 1
    while True:
        t1 = time.perf_counter()
        pb = problem.with_steps(n)
        guess = rescaled_guess(best, n) if best is not None else straight_guess(pb)
        out, eq = _decide(pb, guess, expect_feasible=hi_feas is None)
        calls += out.solver_calls
        trace.append(SearchStep(N=n, verdict=out.status, method=out.method,
                                seconds=time.perf_counter() - t1))
        if out.status == "solved":
            best = finish(pb, eq, out, t1)
            hi_feas = n
        elif out.status == "infeasible" or out.certificate is not None:
            # a claim of infeasibility whose certificate does not check out is searched as
            # one (a larger N is tried) and kept as not valid: the plan says it is not
            # proven fastest, and the plan at N* is verified like any
            lo_inf, cert = n, out.certificate
        else:
            raise SolverError(f"minimum time: the solve at N = {n} failed ({out.detail})")
        if hi_feas is not None and (hi_feas - 1 == (lo_inf if lo_inf is not None else floor - 1)):
            break
        if hi_feas is None:  # still infeasible: gallop up (trying n_max itself last)
            if n >= n_max:
                raise InfeasibleError(f"no feasible plan with N ≤ {n_max} steps: the goal cannot be "
                                      "reached inside the region under this speed bound",
                                      Issue.NO_PLAN_WITHIN_N_MAX)
            n = min(n + step, n_max)
            step *= 2
        elif lo_inf is None:  # feasible: step down, galloping
            n = max(floor, hi_feas - step)
            step *= 2
        else:
            n = (lo_inf + hi_feas) // 2
    assert best is not None
    if lo_inf is not None and cert is not None and lo_inf == best.N - 1:
        pass
    else:
        cert = None
    return MintimeResult("optimal", best, best.N, cert, len(trace), calls,
                         time.perf_counter() - t0, trace)


def solve_mintime(model: ServoModel, start_deg: F, goal_deg: F, region: Region, vmax: float,
                  intersample: int = 1, hold_first: bool = True, ref_lo_deg: F | None = None,
                  ref_hi_deg: F | None = None) -> MintimeResult:
    """Minimum-time references (31) from ``start_deg`` to ``goal_deg`` under ``vmax`` (deg/s)."""
    pb = PlanProblem(model, np.asarray(start_deg, float), np.asarray(goal_deg, float), 2, region,
                     vmax, intersample, hold_first, ref_lo_deg, ref_hi_deg)
    return solve_mintime_problem(pb)
