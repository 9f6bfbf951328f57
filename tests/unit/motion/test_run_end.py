"""One rule for how a run log closes on an exception, whatever the run (execute, home, follow,
commissioning): the outcome names what ended it, the exit code is the error's own."""

from __future__ import annotations

from spm_console.errors import (
    BadInputError,
    EStopError,
    ExitCode,
    InterruptedBySignalError,
)
from spm_console.motion.logs.run_end import RunEnd, run_end


def test_each_kind_of_end_has_its_outcome_and_exit_code() -> None:
    assert run_end(EStopError("E-stop: SIGINT")) == RunEnd(
        "stopped", int(ExitCode.STOP_ESTOP), "E-stop: SIGINT")
    assert run_end(InterruptedBySignalError("SIGTERM")) == RunEnd(
        "interrupted", int(ExitCode.INTERRUPTED), "SIGTERM")
    refused = run_end(BadInputError("no such pose"))
    assert refused.outcome == "refused" and refused.exit_code == int(BadInputError.exit_code)
    bug = run_end(ZeroDivisionError("x"))
    assert bug.outcome == "error" and bug.exit_code == 1 and "ZeroDivisionError" in bug.message
