"""Switches read from the environment."""

from __future__ import annotations

import os

#: The words that switch a feature off (any case, surrounding blanks ignored).
OFF_WORDS = ("0", "no", "off", "false")


def switched_off(name: str) -> bool:
    """Whether the environment variable ``name`` says off (``0``, ``no``, ``off``,
    ``false``); unset, empty or anything else leaves the feature on."""
    return os.environ.get(name, "").strip().lower() in OFF_WORDS


#: The environment variable that sets the emulated bus's clock for every session of the
#: process and its children, over the profile's ``[emulator]`` settings: ``real``,
#: ``simulated`` (as fast as computed) or ``simulated:RATE`` (RATE simulated seconds per
#: wall-clock second). A test suite runs its motions in simulated time with it.
CLOCK_VAR = "SPM_CONSOLE_CLOCK"
#: Largest pace of ``simulated:RATE`` (times real time).
MAX_RATE = 1000.0


def clock_override() -> tuple[str, float] | None:
    """(``real`` or ``simulated``, pace) from :data:`CLOCK_VAR` (any case; pace 0: as fast
    as computed); None when unset or empty. ValueError for another value."""
    raw = os.environ.get(CLOCK_VAR, "").strip().lower()
    if not raw:
        return None
    kind, sep, rate_text = raw.partition(":")
    kind = kind.strip()
    rate = 0.0
    if sep:
        try:
            rate = float(rate_text)
        except ValueError:
            rate = -1.0
    if kind not in ("real", "simulated") or (sep and kind == "real") or not (
            0.0 < rate <= MAX_RATE or not sep):
        raise ValueError(f"{CLOCK_VAR}={raw!r}: expected real, simulated or simulated:RATE "
                         f"(0 < RATE ≤ {MAX_RATE:g}, times real time)")
    return kind, rate
