"""How a run log closes when an exception ends its run: one rule for every kind of run."""

from __future__ import annotations

from dataclasses import dataclass

from spm_console.errors import EStopError, InterruptedBySignalError, SpmError


@dataclass(frozen=True)
class RunEnd:
    """A run log's closing outcome, exit code and message."""

    outcome: str
    """``stopped`` (an E-stop once the wrist moved), ``interrupted`` (a signal before it moved),
    ``refused`` (any other operator error) or ``error`` (a bug)."""
    exit_code: int
    message: str


def run_end(exc: BaseException) -> RunEnd:
    """The end of a run that ``exc`` ended."""
    if isinstance(exc, SpmError):
        outcome = ("stopped" if isinstance(exc, EStopError) else
                   "interrupted" if isinstance(exc, InterruptedBySignalError) else "refused")
        return RunEnd(outcome, int(exc.exit_code), exc.message)
    return RunEnd("error", 1, f"internal error: {type(exc).__name__} (see stderr)")
