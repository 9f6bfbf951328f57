"""Error types and the one mapping from error to process exit code.

The headless CLI is an API: every operator-facing failure is an ``SpmError``
subclass carrying a distinct :class:`ExitCode`. Nothing here imports UI or I/O.
"""

from __future__ import annotations

from enum import IntEnum, StrEnum

from spm_console.refusals import Refusal, worded


class ExitCode(IntEnum):
    """Process exit codes of ``spm-console`` (documented in docs/cli-reference.md, "Exit codes")."""

    OK = 0
    INTERNAL = 1
    USAGE = 2
    PROFILE_ERROR = 3
    BAD_INPUT = 4
    UNREACHABLE = 5
    INFEASIBLE = 6
    SOLVER_FAILED = 7
    CACHE_ERROR = 8
    PLAN_MISMATCH = 9
    BUS_ERROR = 10
    ASSERTION_FAILED = 11
    CLUSTER_LOST = 12
    STOP_ESTOP = 20
    STOP_TRACKING = 21
    STOP_COMM = 22
    STOP_HW_ERROR = 23
    STOP_REGION = 24
    STOP_LIMIT = 25
    PLAN_REFUSED = 26
    MOTION_PROCESS_LOST = 27
    INTERRUPTED = 130


class Issue(StrEnum):
    """What went wrong, for a front end to pick its advice (the key, field or step to use)
    by, never by the message's words; the message itself names no front end's keys."""

    NOT_CONNECTED = "not_connected"
    """The servos are not connected."""
    MOVING = "moving"
    """The wrist is moving: the request waits until it stops."""
    NO_WORKSPACE = "no_workspace"
    """No workspace is loaded."""
    NO_PLAN = "no_plan"
    """No plan to execute."""
    POSE_UNKNOWN = "pose_unknown"
    """The current pose was asked for before the servos were read."""
    TOO_FEW_STEPS = "too_few_steps"
    """The plan's N steps are too few for the move or its route of regions."""
    SPEED_TOO_LOW = "speed_too_low"
    """The speed bound is below what any allowed horizon needs (the message names the
    speed needed)."""
    NO_PLAN_WITHIN_N_MAX = "no_plan_within_n_max"
    """No plan within the largest horizon."""
    TOO_MANY_INSTANTS = "too_many_instants"
    """N times the intersample count K is above the bound of constrained instants."""
    END_NOT_FEASIBLE = "end_not_feasible"
    """A start or goal is outside the servo or reference limits, or not feasible; or the
    straight segment between them leaves the feasible set, the workspace has no feasible
    node, or the motion planned between them leaves the servo limits."""


class SpmError(Exception):
    """Base class of every error shown to an operator (message, no traceback);
    :attr:`issue` says what went wrong when a front end gives advice for it."""

    exit_code: ExitCode = ExitCode.INTERNAL
    issue: Issue | None = None

    def __init__(self, message: str, issue: Issue | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.issue = issue

    def at(self, where: str) -> SpmError:
        """This error (its class, exit code and issue kept) with ``where`` (a file, a step and
        key, a row) before its message: ``raise exc.at(source) from None``."""
        self.message = f"{where}: {self.message}"
        self.args = (self.message,)
        return self


class ProfileError(SpmError):
    """A profile file is missing, unreadable or invalid (names file, key, reason)."""

    exit_code = ExitCode.PROFILE_ERROR


class BadInputError(SpmError):
    """A value given by the operator is malformed or out of range."""

    exit_code = ExitCode.BAD_INPUT


class OptionConflictError(SpmError):
    """Options given together that do not go together, which the parser cannot tell alone
    (one needs another's value): a bad command line, exit 2 as the parser's own."""

    exit_code = ExitCode.USAGE


class UnreachableError(SpmError):
    """No solution in the home assembly/working mode (e.g. the path crosses a singularity)."""

    exit_code = ExitCode.UNREACHABLE


class InfeasibleError(SpmError):
    """A configuration or problem violates the workspace / planning constraints."""

    exit_code = ExitCode.INFEASIBLE


class SolverError(SpmError):
    """A numerical solver failed to produce a certified answer."""

    exit_code = ExitCode.SOLVER_FAILED


class CacheError(SpmError):
    """A cache file is corrupt or unreadable."""

    exit_code = ExitCode.CACHE_ERROR


class PlanMismatchError(SpmError):
    """A plan file does not match the profile, or is corrupt."""

    exit_code = ExitCode.PLAN_MISMATCH


class BusError(SpmError):
    """The servo bus cannot be opened, or a servo is absent or of the wrong model."""

    exit_code = ExitCode.BUS_ERROR


class ImuError(SpmError):
    """The IMU cannot be opened, does not answer, is not the chip expected, or refused a
    request. Exit 10 like the servo bus (a device on a serial port missing or of the wrong
    model: an input or hardware problem, not a bug); a class of its own, so that the servo
    bus's handlers never take it for theirs."""

    exit_code = ExitCode.BUS_ERROR


class PlanRefusedError(SpmError):
    """The runtime's own verification refused a plan before torque-on (the motion would
    leave the certified feasible set, or exceed a speed, step or servo limit)."""

    exit_code = ExitCode.PLAN_REFUSED


class RefusedError(BadInputError):
    """A request refused for the state of the wrist: :attr:`reason` says which precondition
    failed (the message is the runtime's own wording, which names no front end's keys)."""

    def __init__(self, reason: Refusal | str, message: str = "") -> None:
        self.reason = Refusal(reason)
        super().__init__(message or worded(self.reason, "runtime"))


class InterruptedBySignalError(SpmError):
    """A terminating signal (SIGINT, SIGTERM, SIGHUP, SIGQUIT) arrived while nothing moved."""

    exit_code = ExitCode.INTERRUPTED


class EStopError(SpmError):
    """The operator's E-stop (a key, a terminating signal) ended work that had moved the
    wrist; the wrist holds where it stopped."""

    exit_code = ExitCode.STOP_ESTOP


class RunLogError(SpmError):
    """A run's log cannot be written while the wrist moves (a full disk, its folder gone): the
    run stops as an E-stop stops it, the wrist holding, since a run must be logged."""

    exit_code = ExitCode.STOP_ESTOP


class ClusterLostError(SpmError):
    """The Dask cluster of a design sweep went away (scheduler lost, tasks cancelled): the
    designs done are kept and the same command resumes."""

    exit_code = ExitCode.CLUSTER_LOST


class BuildCancelledError(SpmError):
    """The operator cancelled a workspace build. A front end raises it from the progress
    callback it passes to the build, so the build stops at its next progress report; the
    cache is written only after a complete build, so nothing half-built is kept."""

    exit_code = ExitCode.INTERRUPTED


class MotionProcessLostError(SpmError):
    """The motion process (the servo loop's own process) died or stopped answering; the
    servos' Bus Watchdog stops them if a motion was running."""

    exit_code = ExitCode.MOTION_PROCESS_LOST


def error_for(exit_code: int, message: str, reason: str = "") -> SpmError:
    """The error of this exit code (the most specific class), e.g. one that crossed a process;
    a refusal's reason (:class:`Refusal`) makes it a :class:`RefusedError`."""
    if reason:
        return RefusedError(reason, message)
    for cls in _by_code():
        if int(cls.exit_code) == int(exit_code):
            return cls(message)
    err = SpmError(message)
    try:
        err.exit_code = ExitCode(int(exit_code))
    except ValueError:
        err.exit_code = ExitCode.INTERNAL
    return err


def _by_code() -> list[type[SpmError]]:
    out: list[type[SpmError]] = []
    todo = list(SpmError.__subclasses__())
    while todo:
        cls = todo.pop(0)
        out.append(cls)
        todo.extend(cls.__subclasses__())
    return out
