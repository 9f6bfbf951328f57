"""Why the motion process refuses a request for the state of the wrist, and the one table of
words each front end says it with.

The motion process decides every precondition of a motion (homed first, nothing else moving)
and answers with a :class:`Refusal` code (a :class:`~spm_console.errors.RefusedError` on the
client). Its own words name no front end's keys; the CLI, the console and scripts add theirs
from :data:`WORDS`.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Literal

FrontEnd = Literal["runtime", "cli", "console", "script"]


class Refusal(StrEnum):
    """A precondition of a motion that did not hold."""

    NOT_HOMED = "not_homed"
    """A motion other than homing, and the wrist was not homed in this motion process (or
    torque went off since)."""
    MOVING = "moving"
    """A motion runs: the servo loop owns the bus until it ends."""


WORDS: dict[Refusal, dict[FrontEnd, str]] = {
    Refusal.NOT_HOMED: {
        "runtime": "the wrist is not homed: home it first (or override with a reason)",
        "cli": "the wrist is not homed: run `spm-console home` first, or give --skip-homing "
               "REASON",
        "console": "the wrist is not homed: press 1, then h to home it",
        "script": "the wrist is not homed: add a home step first",
    },
    Refusal.MOVING: {
        "runtime": "the wrist is moving: the servo loop owns the bus until the motion ends",
        "cli": "the wrist is moving: the servo loop owns the bus until the motion ends",
        "console": "the wrist is moving: wait, or press SPACE to stop it",
        "script": "the wrist is moving: wait for the step under way to end",
    },
}


def worded(reason: Refusal, front_end: FrontEnd) -> str:
    """The words ``front_end`` says ``reason`` with."""
    return WORDS[reason][front_end]
