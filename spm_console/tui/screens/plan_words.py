"""The plan step's words: a solved plan's summary (:func:`plan_text`), and what to do in
the console after a failed solve (:func:`next_step`): which field to change or which key
to press, never a shell command.

The planner's messages are shared with the CLI and may name its commands or options
("use more steps or 'plan mintime'"); :func:`console_words` puts the console's words in
their place, and :func:`next_step` picks the "Next:" line by what went wrong (the error's
:class:`~spm_console.errors.Issue`), never by the message's words.
"""

from __future__ import annotations

import math

from spm_console.core.plan import Plan
from spm_console.core.plan_rules import BETWEEN_SPEED_ALLOWANCE
from spm_console.errors import Issue
from spm_console.formatting import fmt_deg
from spm_console.services.plan_store import PlanInfo
from spm_console.tui.widgets.steps import keys_of

#: CLI wording in planner messages → what it means on the plan step.
_CLI_WORDS: tuple[tuple[str, str], ...] = (
    ("'plan mintime'", "the minimum-time method (Method dropdown)"),
    ("'plan mvn'", "the MVN method (Method dropdown)"),
    ("--steps", "the steps N field"),
    ("--vmax", "the v_max field"),
    ("--intersample", "the intersample K field"),
    ("--free-first", "the 'free first reference' box"),
)

_FIELDS = "tab moves from field to field"

#: What to do next after a failed solve, by what went wrong.
_NEXT: dict[Issue, str] = {
    Issue.POSE_UNKNOWN:
        f"connect first (press {keys_of('connect')}, then c), or choose 'home' or motor "
        "angles θ as the start; then press s.",
    Issue.TOO_FEW_STEPS:
        "raise steps N (the 'steps N' field; " + _FIELDS + "), or choose 'minimum time' in the "
        "Method dropdown (it finds the shortest N itself); then press s.",
    Issue.SPEED_TOO_LOW:
        "raise v_max in the 'v_max °/s' field (" + _FIELDS + ") to at least the speed named "
        "above, or choose a goal nearer the start; then press s.",
    Issue.NO_PLAN_WITHIN_N_MAX:
        "raise v_max in the 'v_max °/s' field, or choose a goal nearer the start; then press s.",
    Issue.TOO_MANY_INSTANTS:
        "lower steps N or the intersample K field (" + _FIELDS + "); then press s.",
    Issue.END_NOT_FEASIBLE:
        "change the start or goal fields (the θ or r/p/y you typed, " + _FIELDS + "); the "
        f"workspace step checks a θ first ({keys_of('workspace')}, then k); then press s.",
}

_GENERIC = ("change the start, the goal, the method, steps N or v_max (" + _FIELDS + "), "
            "then press s.")


def console_words(message: str) -> str:
    """``message`` with any CLI command or option replaced by the console's words."""
    for cli, here in _CLI_WORDS:
        message = message.replace(cli, here)
    return message


def next_step(issue: Issue | None) -> str:
    """The "Next:" advice for a solve that failed with ``issue`` (keys and fields)."""
    return _GENERIC if issue is None else _NEXT.get(issue, _GENERIC)


#: How the console names a plan's kind (the CLI's ``mvn`` / ``mintime``).
KIND_WORDS = {"mvn": "MVN", "mintime": "Minimum time"}


def plan_text(plan: Plan, info: PlanInfo) -> str:
    """The plan step's summary of ``plan`` (:meth:`Plan.summary`); ``info`` is the session's
    words for it (how start and goal were given, the region, the file it came from)."""
    s = plan.summary()
    chk = s.check
    vmax = s.vmax_degps if s.vmax_degps is not None else info.vmax_degps
    read = " (read from the servos just before solving)" if info.start_read else ""
    lines = [
        f"{KIND_WORDS.get(s.kind, s.kind)}: {info.start} → {info.goal}",
        f"start θ = {fmt_deg(info.start_deg)}{read}",
        f"goal θ = {fmt_deg(info.goal_deg)}",
        f"N = {s.N} × {s.Ts:g} s = {s.duration_s:.2f} s, cost {s.cost:.1f} (deg/s)²",
        f"solved in {s.solve_seconds:.2f} s ({s.qp_count} QP)",
        f"max |dθ/dt| {s.max_speed_degps:.1f}°/s at samples" + (f" (v_max {vmax:g})" if vmax else ""),
    ]
    if info.region:
        lines.append(f"region: {info.region}")
    if info.source:
        lines.append(f"opened from {info.source}")
    if chk is not None:
        if not math.isnan(chk.max_speed_between_degps):
            allowed = (f" (allowed: v_max + {BETWEEN_SPEED_ALLOWANCE:.0%} between samples)"
                       if vmax else "")
            lines.append(f"between samples: {chk.max_speed_between_degps:.1f}°/s{allowed}, "
                         f"outside the plan's region by {chk.region_violation_between_deg:.2g}°")
        lines.append("constraints verified" if s.verified else "constraints NOT verified")
    if s.certificate is not None:  # minimum time: N is the smallest feasible horizon
        lines.append(proof_text(plan))
    return "\n".join(lines)


def proof_text(plan: Plan) -> str:
    """What a minimum-time plan's infeasibility certificate proves, for an operator: no
    reference reaches the goal one step sooner within the plan's limits (the CLI prints the
    certificate's numbers)."""
    rec = plan.certificate
    assert rec is not None
    n = rec.N
    if rec.certificate is None:
        return f"fastest possible: N = {n + 1} steps is the fewest a plan can have"
    claim = (f"no reference reaches the goal in N−1 = {n} steps ({n * plan.Ts:.2f} s) within "
             "these limits (v_max, the servo limits, the workspace region"
             + (", along this route of regions: another route might be faster)" if rec.scope
                else ")"))
    if rec.certificate.valid:
        return f"fastest possible: {claim}; proven by a checked infeasibility certificate"
    return (f"NOT proven fastest: the proof that {claim} did not check out, so a shorter "
            "plan may exist")
