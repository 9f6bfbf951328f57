"""Messages that workers post to screens (the only way blocking work reports back)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from textual.message import Message

if TYPE_CHECKING:
    from spm_console.core.plan import Plan
    from spm_console.core.workspace.check import ThetaCheck
    from spm_console.errors import Issue
    from spm_console.motion.follow.run import FollowOutcome
    from spm_console.motion.logs.runlog import RunData
    from spm_console.motion.segments import ExecutionResult
    from spm_console.motion.servo_tools import ServoHealth
    from spm_console.services.kin_record import FkRecord
    from spm_console.services.preview import Preview
    from spm_console.services.session import BusState


# --- what a blocking operation produced: one dataclass per outcome --------------------------
@dataclass(frozen=True)
class Connected:
    state: BusState
    restarted_emulator: bool = False
    """A connection replaced an emulated one: the emulated servos started again (at the
    profile's initial pose, torque off, not homed)."""


@dataclass(frozen=True)
class PositionRead:
    theta_deg: Any
    """Measured motor angles, deg."""


@dataclass(frozen=True)
class MotionDone:
    kind: Literal["home", "execute", "jog"]
    result: ExecutionResult


@dataclass(frozen=True)
class PreviewDone:
    """The plan's run on the wrist's twin in simulated time (nothing moved)."""

    preview: Preview


@dataclass(frozen=True)
class FollowDone:
    """A live following (the console's live jog) ended: its run and its re-planning figures."""

    outcome: FollowOutcome


@dataclass(frozen=True)
class ServoToolDone:
    """A servo tool ran on one joint; every joint's health read after it."""

    action: Literal["torque on", "torque off", "reboot"]
    joint: int
    health: ServoHealth


@dataclass(frozen=True)
class FkSolved:
    record: FkRecord
    """The solved FK (:meth:`~spm_console.services.session.Session.fk`)."""
    from_ik: bool = False
    rpy_deg: Any = None
    """Roll, pitch, yaw from home (deg) of an FK result, when θ is that orientation's IK."""


@dataclass(frozen=True)
class WorkspaceLoaded:
    pass


@dataclass(frozen=True)
class ThetaChecked:
    check: ThetaCheck


@dataclass(frozen=True)
class PlanSolved:
    plan: Plan


@dataclass(frozen=True)
class PlanSaved:
    path: Path


@dataclass(frozen=True)
class PlanLoaded:
    """A saved plan, checked against the profile and verified, is the current plan."""

    plan: Plan
    path: str


@dataclass(frozen=True)
class RunOpened:
    run: RunData


@dataclass(frozen=True)
class IdentifyDone:
    """The identification experiment ended: its run, and when it completed the identified
    profile and the plot written, a summary (one line) and the whole result (the lines of
    ``identify --experiment``)."""

    result: ExecutionResult
    profile: Path | None
    plot: Path | None
    summary: str
    lines: tuple[str, ...] = ()


@dataclass(frozen=True)
class CommissionDone:
    """Commissioning (step 0) completed: the profile written, the result in words (the lines
    of ``commission``) and each leg's servo id and direction in short."""

    written: Path
    lines: tuple[str, ...]
    ids_text: str


@dataclass(frozen=True)
class BenchmarkDone:
    """Benchmarks' own blocking work (no screen shows it)."""

    value: Any = None


Outcome = (Connected | PositionRead | MotionDone | FkSolved | WorkspaceLoaded | ThetaChecked
           | PlanSolved | PlanSaved | PlanLoaded | RunOpened | BenchmarkDone | ServoToolDone
           | FollowDone | IdentifyDone | CommissionDone | PreviewDone)


class Done(Message):
    """A blocking operation finished with ``outcome``."""

    def __init__(self, op: str, outcome: Outcome) -> None:
        super().__init__()
        self.op = op
        self.outcome = outcome


class Failed(Message):
    """A blocking operation failed with a message for the operator (no traceback)."""

    def __init__(self, op: str, message: str, solver_failed: bool = False,
                 issue: Issue | None = None) -> None:
        super().__init__()
        self.op = op
        self.message = message
        self.solver_failed = solver_failed
        """A solver (or the code) failed; False when the request was refused with a reason
        (bad input, an end not feasible, no feasible plan)."""
        self.issue = issue
        """What went wrong (:attr:`SpmError.issue <spm_console.errors.SpmError.issue>`), for
        the screen's advice."""


class Telemetry(Message):
    """The latest executor sample. Bursts coalesce: only the newest is handled."""

    def __init__(self, sample: Any) -> None:
        super().__init__()
        self.sample = sample

    def can_replace(self, message: Message) -> bool:
        return isinstance(message, Telemetry)


class Progress(Message):
    """Progress of a long build: stage name and fraction in [0, 1]. Bursts coalesce."""

    def __init__(self, stage: str, fraction: float) -> None:
        super().__init__()
        self.stage = stage
        self.fraction = fraction

    def can_replace(self, message: Message) -> bool:
        return isinstance(message, Progress)
