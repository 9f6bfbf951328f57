"""What to do in the console after a failed solve on the plan step: which field to change
or which key to press, never a shell command.

The planner's messages are shared with the CLI and may name its commands or options
("use more steps or 'plan mintime'"); :func:`console_words` puts the console's words in
their place, and :func:`next_step` picks the "Next:" line from what the message says went
wrong.
"""

from __future__ import annotations

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
     f"workspace step ({keys_of('workspace')}) checks a θ first (k); then press s."),
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
