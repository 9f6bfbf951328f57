"""Honest checks of a planned reference: simulate the model and measure every constraint.

The positions and velocities reported in a plan are those of the servo model
driven by the references (not the optimizer's internal states); this module
computes them and the worst violation of each constraint at the samples, and
the worst speed and region excursion of the continuous motion between samples.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from spm_console.core.plan_report import ConstraintReport
from spm_console.core.plan_rules import SAMPLE_TOL, MotionCheck, check_motion
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.servo.model import simulate, simulate_continuous

F = NDArray[np.float64]

#: Points per interval of the between-sample simulation of the report: at least as many as
#: the runtime's check (:data:`~spm_console.core.plan_rules.POINTS_PER_INTERVAL`).
BETWEEN_POINTS = 20


def simulate_plan(problem: PlanProblem, reference: F) -> tuple[F, F]:
    """(positions (N+1, 3) deg, velocities (N+1, 3) deg/s) of the model under ``reference``."""
    x0 = np.column_stack([problem.start_deg, np.zeros(3)])
    xs = simulate(problem.model, x0, reference)
    return xs[..., 0].copy(), xs[..., 1].copy()


def runtime_check(problem: PlanProblem, reference: F, samples: F | None = None) -> MotionCheck:
    """The runtime's rules (:func:`~spm_console.core.plan_rules.check_motion`) on
    ``reference`` as the runtime applies them to a planned segment: from rest at θ*(0), with
    the reference limits as the servo limits, the problem's speed bound and linear range.
    All but the certification (rule 7): that is the workspace's certified set, which a pure
    planner does not have (:func:`spm_console.services.plan_request.plan_motion` checks it
    with the runtime's own verification; the regions a planner uses lie in it, and the
    report's ``region_violation_between_deg`` says how far the motion leaves them).
    ``samples``: the model's states at the samples from rest at θ*(0), when known."""
    inf = np.full(3, np.inf)
    lo = -inf if problem.ref_lo_deg is None else problem.ref_lo_deg
    hi = inf if problem.ref_hi_deg is None else problem.ref_hi_deg
    vmax = np.inf if problem.vmax_degps is None else float(problem.vmax_degps)
    x0 = np.column_stack([reference[0], np.zeros(3)])
    return check_motion(problem.model.dynamics, problem.model.ts, x0, reference, lo, hi, vmax,
                        None, lead_max_deg=problem.lead_max_deg, samples=samples)


def check(problem: PlanProblem, reference: F, position: F | None = None,
          velocity: F | None = None) -> tuple[ConstraintReport, F, F]:
    """Simulate ``reference`` and measure its constraints; returns (report, θ, θ̇). The
    report's verdict is the runtime's (:func:`runtime_check`) and the planner's own metrics
    together: a plan whose report is ok is one the runtime's rules accept."""
    pos, vel = simulate_plan(problem, reference)
    mismatch = 0.0
    if position is not None:
        mismatch = max(mismatch, float(np.abs(position - pos).max()))
    if velocity is not None:
        mismatch = max(mismatch, float(np.abs(velocity - vel).max()))
    vmax = problem.vmax_degps
    route = problem.regions
    N = len(reference) - 1
    reg_viol = float(route.violation_deg(pos, route.sample_mask(N)).max())
    speed = float(np.abs(vel).max())
    speed_ex = max(0.0, speed - vmax) if vmax is not None else 0.0
    ref_ex = 0.0
    k0 = 1 if problem.hold_first else 0
    free = reference[k0:-1]
    if problem.ref_lo_deg is not None and free.size:
        ref_ex = max(ref_ex, float((problem.ref_lo_deg - free).max()))
    if problem.ref_hi_deg is not None and free.size:
        ref_ex = max(ref_ex, float((free - problem.ref_hi_deg).max()))
    ref_ex = max(ref_ex, 0.0)
    hold_err = float(np.abs(reference[0] - problem.start_deg).max()) if problem.hold_first else 0.0
    goal_err = max(float(np.abs(pos[-1] - problem.goal_deg).max()),
                   float(np.abs(reference[-1] - problem.goal_deg).max()))

    pts = problem.intersample * int(np.ceil(BETWEEN_POINTS / problem.intersample))
    x0 = np.column_stack([problem.start_deg, np.zeros(3)])
    known = np.stack([pos, vel], axis=-1) if problem.model.method == "zoh" else None
    # the runtime starts from rest at θ*(0): the same states when θ*(0) is the start exactly
    same_start = known is not None and bool(np.array_equal(reference[0], problem.start_deg))
    runtime = runtime_check(problem, reference, known if same_start else None)
    _, xs = simulate_continuous(problem.model.dynamics, problem.model.ts, x0, reference, pts, known)
    vb = float(np.abs(xs[..., 1]).max())
    # the continuous motion: point m lies in interval min(m // pts, N − 1)
    where = np.minimum(np.arange(len(xs)) // pts, N - 1)
    between_mask = route.interval_mask(N)[where]
    rb = float(route.violation_deg(xs[..., 0], between_mask).max())
    sub_viol = 0.0
    if problem.intersample > 1:
        step = pts // problem.intersample
        sub = xs[::step]
        sub_viol = float(route.violation_deg(sub[..., 0], between_mask[::step]).max())
        if vmax is not None:
            sub_viol = max(sub_viol, float(np.abs(sub[..., 1]).max()) - vmax)
    report = ConstraintReport(
        start_error_deg=hold_err,
        goal_error_deg=goal_err,
        final_speed_degps=float(np.abs(vel[-1]).max()),
        model_mismatch=mismatch,
        region_violation_deg=reg_viol,
        speed_excess_degps=speed_ex,
        reference_excess_deg=ref_ex,
        max_speed_samples_degps=speed,
        max_speed_between_degps=vb,
        speed_excess_between_degps=max(0.0, vb - vmax) if vmax is not None else 0.0,
        region_violation_between_deg=rb,
        intersample_violation=max(sub_viol, 0.0),
        points_per_interval=pts,
        ok=max(hold_err, goal_err, float(np.abs(vel[-1]).max()), reg_viol, speed_ex, ref_ex,
               sub_viol) <= SAMPLE_TOL and runtime.ok,
        runtime_rule="" if runtime.violation is None else runtime.violation.rule.value,
    )
    return report, pos, vel
