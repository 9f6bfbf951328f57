"""Planning with an identified servo model: the constraints it adds, timed.

The servo model ``identify --experiment --sim --plant physical`` found on the default profile
(this VM, session 20): ωn 44.03 rad/s, ζ 0.786, delay 5.3 ms, linear range 3.57°, residual
bound 0.19° (and a load, which planning does not see: the runtime adds its offset). With it
the planner holds the lead |θ* − θ| ≤ the linear range at every sample, plans in the region
tightened by the residual bound (the tube), and samples the underdamped model exactly.

Rows (best of 5 wall times, nothing else running):
* the solve of the paper's MVN pair (N = 150) as ``plan_motion`` poses it (region around the
  segment, tube, lead; bounded at the samples, or at 5 instants per interval when the
  runtime's verification refuses that, as ``plan_motion`` re-solves): target ≤ 10 ms;
* the paper's minimum-time pair at 50 °/s and at 200 °/s (a profile bound of 250 °/s):
  target ≤ 50 ms;
* live following's re-plan (H = 50, lead bound on) over the 0.5 Hz ±10° roll of
  ``bench_follow``, the servo model's own response closing the loop: p99 target ≤ 2 ms.
Baseline column: the same request with the paper's model (27), p = 32.22, same run.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from benchmarks.bench_follow import _loop, _ms, _region, roll_targets
from benchmarks.common import Row, timeit
from spm_console.config.load import load_profile
from spm_console.config.models import model_of, servo_limits_deg, servo_model_of
from spm_console.config.schema import Profile
from spm_console.core.plan import Plan
from spm_console.core.planning.follow.solver import FollowSolver
from spm_console.core.planning.mintime import solve_mintime_problem
from spm_console.core.planning.mvn import solve_problem
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.polytope.region import INSIDE_TOL_DEG, Region
from spm_console.core.regions.choice import choose_region
from spm_console.errors import PlanRefusedError
from spm_console.motion.plan_check import verify_plan
from spm_console.report import paper_values as pv
from spm_console.services.plan_request import tube
from spm_console.store.plan_file import plan_hash
from spm_console.store.workspace_cache import load_or_build

F = NDArray[np.float64]
PROFILE = "profiles/agile_wrist.toml"
IDENTIFIED = {"p": 44.03, "zeta": 0.786, "delay_s": 0.0053, "linear_range_deg": 3.57,
              "residual_bound_deg": 0.19}


def _identified(prof: Profile, vmax: float | None = None) -> Profile:
    upd: dict[str, object] = {"servo": prof.servo.model_copy(update=IDENTIFIED)}
    if vmax is not None:
        upd["limits"] = prof.limits.model_copy(update={"vmax_degps": vmax})
    return prof.model_copy(update=upd)


def _solve(pb: PlanProblem, method: str) -> Plan:
    if method == "mvn":
        return solve_problem(pb).to_plan("mvn")
    return solve_mintime_problem(pb).to_plan("mintime")


def _plan_rows(paper: Profile) -> list[Row]:
    """The solve of the problem :func:`plan_motion` builds (region around the segment, the
    tube, the lead), at the fewest instants per interval the runtime's verification accepts
    (1, else the planner's re-solve at 5), timed; the paper's model on the same region and
    the same K is the baseline."""
    ws, _ = load_or_build(paper)
    fast_paper = paper.model_copy(update={"limits": paper.limits.model_copy(
        update={"vmax_degps": 250.0})})
    cases = [("MVN paper pair, N=150", "mvn", pv.MVN_START_DEG, None, paper, 10.0),
             ("min time paper pair, 50°/s", "mintime", pv.MINTIME_START_DEG,
              pv.MINTIME_VMAX_DEGPS, paper, 50.0),
             ("min time paper pair, 200°/s", "mintime", pv.MINTIME_START_DEG, 200.0,
              fast_paper, 50.0)]
    rows = []
    for name, method, start, vmax, base, target in cases:
        s, g = np.asarray(start, float), np.asarray(pv.MVN_GOAL_DEG, float)
        ident = _identified(base)
        lo, hi = servo_limits_deg(ident)
        v = float(vmax if vmax is not None else base.limits.vmax_degps)
        both = np.stack([s, g])
        region = (ws.region if ws.region.contains(both, tol=INSIDE_TOL_DEG).all()
                  else choose_region(ws, s, g).region)

        def problem(prof: Profile, k: int, region: Region = region, s: F = s, g: F = g,
                    v: float = v, lo: F = lo, hi: F = hi) -> PlanProblem:
            return PlanProblem(servo_model_of(prof), s, g, pv.MVN_STEPS, tube(prof, region, s, g),
                               v, k, True, lo, hi, lead_max_deg=prof.servo.linear_range_deg)

        plan = _solve(problem(ident, 1), method)
        try:
            verify_plan(ident, ws, replace(plan, profile_hash=plan_hash(ident)))
            used = 1
        except PlanRefusedError:
            used = 0
        pb_ours, pb_base = problem(ident, max(used, 1)), problem(base, max(used, 1))
        ours = timeit(lambda: _solve(pb_ours, method), repeat=5)  # noqa: B023 (used at once)
        before = timeit(lambda: _solve(pb_base, method), repeat=5)  # noqa: B023
        rows.append(Row(f"identified: plan {name}", ours * 1e3, "ms", f"<= {target:g} ms",
                        before * 1e3, used > 0 and ours * 1e3 <= target,
                        f"N = {plan.N}; bounded at the samples and the runtime's check instants"
                        f" ({'accepted' if used else 'refused'} by the runtime's "
                        f"verification); the identified model's lead, tube and exact "
                        f"underdamped sampling; baseline: the paper's model, same problem"))
    return rows


def run() -> list[Row]:
    paper = load_profile(PROFILE)
    rows = _plan_rows(paper)
    ident = _identified(paper)
    model = servo_model_of(ident)
    lo, hi = servo_limits_deg(ident)
    region, src = _region(PROFILE)
    home = np.asarray(paper.home.theta_deg, float)
    spm = model_of(paper)
    targets = roll_targets(spm, model.ts)
    vmax = float(paper.limits.vmax_degps)
    solver = FollowSolver(model, region, vmax, 50, lo, hi,
                          lead_max_deg=ident.servo.linear_range_deg)
    _, _, res = _loop(solver, model, home, targets)
    p50, p99, mx = _ms([r.seconds for r in res])
    base_model = servo_model_of(paper)
    _, _, base = _loop(FollowSolver(base_model, region, vmax, 50, lo, hi), base_model, home,
                       targets)
    _, b99, _ = _ms([r.seconds for r in base])
    statuses = sorted({r.status for r in res})
    rows.append(Row("identified: follow re-plan p99 (H=50)", p99, "ms", "<= 0.5 ms", b99,
                    p99 <= 0.5, f"p50 {p50:.2f} ms, max {mx:.2f} ms; lead ≤ "
                    f"{ident.servo.linear_range_deg}°; {src}; statuses {statuses}"))
    return rows
