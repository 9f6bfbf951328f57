"""The plan step's words: a solved plan's summary (:func:`plan_text`), and what to do in
the console after a failed solve (:func:`next_step`): which field to change or which key
to press, never a shell command.

The planner's messages are shared with the CLI and may name its commands or options
("use more steps or 'plan mintime'"); :func:`console_words` puts the console's words in
their place, and :func:`next_step` picks the "Next:" line from what the message says went
wrong.
"""

from __future__ import annotations

import math
from typing import Any

from spm_console.core.plan import Plan
from spm_console.formatting import fmt_deg
from spm_console.motion.plan_check import BETWEEN_SPEED_ALLOWANCE
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

#: (words in the failure's message, what to do next), first match wins.
_NEXT: tuple[tuple[tuple[str, ...], str], ...] = (
    (("current pose unknown",),
     f"connect first (press {keys_of('connect')}, then c), or choose 'home' or motor "
     "angles θ as the start; then press s."),
    (("no reference reaches the goal in N =", "too few for a route", "no room for the route"),
     "raise steps N (the 'steps N' field; " + _FIELDS + "), or choose 'minimum time' in the "
     "Method dropdown (it finds the shortest N itself); then press s."),
    (("use a speed bound of at least",),
     "raise v_max in the 'v_max °/s' field (" + _FIELDS + ") to at least the speed named "
     "above, or choose a goal nearer the start; then press s."),
    (("no feasible plan with N ≤",),
     "raise v_max in the 'v_max °/s' field, or choose a goal nearer the start; then press s."),
    (("constrained instants", "intersample"),
     "lower steps N or the intersample K field (" + _FIELDS + "); then press s."),
    (("outside the servo limits", "NOT feasible", "not feasible", "singular", "collid",
      "below the reference limits", "above the reference limits"),
     "change the start or goal fields (the θ or r/p/y you typed, " + _FIELDS + "); the "
     f"workspace step checks a θ first ({keys_of('workspace')}, then k); then press s."),
)

_GENERIC = ("change the start, the goal, the method, steps N or v_max (" + _FIELDS + "), "
            "then press s.")


def console_words(message: str) -> str:
    """``message`` with any CLI command or option replaced by the console's words."""
    for cli, here in _CLI_WORDS:
        message = message.replace(cli, here)
    return message


def next_step(message: str) -> str:
    """The "Next:" advice for a solve that failed with ``message`` (keys and fields)."""
    for words, advice in _NEXT:
        if any(w in message for w in words):
            return advice
    return _GENERIC


#: How the console names a plan's kind (the CLI's ``mvn`` / ``mintime``).
KIND_WORDS = {"mvn": "MVN", "mintime": "Minimum time"}


def plan_text(plan: Plan, info: dict[str, Any]) -> str:
    """The plan step's summary of ``plan`` (:meth:`Plan.summary`); ``info`` is the session's
    words for it (how start and goal were given, the region, the file it came from)."""
    s = plan.summary()
    chk = s.check
    vmax = s.vmax_degps if s.vmax_degps is not None else info.get("vmax_degps")
    start = info.get("start_deg", s.start_deg)
    read = " (read from the servos just before solving)" if info.get("start_read") else ""
    lines = [
        f"{KIND_WORDS.get(s.kind, s.kind)}: {info.get('start', '?')} → {info.get('goal', '?')}",
        f"start θ = {fmt_deg(start)}{read}",
        f"goal θ = {fmt_deg(info.get('goal_deg', s.goal_deg))}",
        f"N = {s.N} × {s.Ts:g} s = {s.duration_s:.2f} s, cost {s.cost:.1f} (deg/s)²",
        f"solved in {s.solve_seconds:.2f} s ({s.qp_count} QP)",
        f"max |dθ/dt| {s.max_speed_degps:.1f}°/s at samples" + (f" (v_max {vmax:g})" if vmax else ""),
    ]
    if info.get("region"):
        lines.append(f"region: {info['region']}")
    if info.get("source"):
        lines.append(f"opened from {info['source']}")
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
