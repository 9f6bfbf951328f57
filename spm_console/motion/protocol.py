"""Typed messages between a front end and the motion process (:mod:`.server`).

A request that is answered is a :class:`Request` ``[R]``: it carries an ``id`` that the reply
repeats, and ``R`` is the type of the reply's value (the client's call returns an ``R``).
Telemetry carries samples. Everything here pickles (plans and
results are dataclasses of numpy arrays). Degrees and seconds.
"""

from __future__ import annotations

import signal
from dataclasses import dataclass
from typing import TYPE_CHECKING, Generic, TypeVar

import numpy as np
from numpy.typing import NDArray

from spm_console.core.plan import Plan
from spm_console.core.planning.follow.timed import TimedTargets
from spm_console.devices.base import ServoStatus
from spm_console.motion.sample import Sample
from spm_console.motion.servo_query import BusQuery, BusReport

if TYPE_CHECKING:  # the replies' types (named in the requests' bases, as strings)
    from spm_console.motion.follow.run import FollowOutcome  # noqa: F401
    from spm_console.motion.homing import HomingResult  # noqa: F401
    from spm_console.motion.nudge import NudgeResult  # noqa: F401
    from spm_console.motion.plan_check import PlanCheck  # noqa: F401
    from spm_console.motion.segments import ExecutionResult  # noqa: F401
    from spm_console.motion.servo_tools import ServoHealth  # noqa: F401

R = TypeVar("R", covariant=True)

#: The signal a client sends the motion process for an E-stop when the connection is gone.
ESTOP_SIGNAL = signal.SIGUSR1


class Request(Generic[R]):
    """A request the motion process answers with a :class:`Reply` whose value is an ``R``
    (or a :class:`Failed`)."""

    __slots__ = ()
    id: int


@dataclass(frozen=True)
class Ping(Request[list[ServoStatus]]):
    """Ping every servo; reply: list of ServoStatus (with temperature and voltage)."""

    id: int


@dataclass(frozen=True)
class ReadPosition(Request[NDArray[np.float64]]):
    """Measured θ (deg), read with set-up retries."""

    id: int


@dataclass(frozen=True)
class Status(Request["ServoHealth"]):
    """Every joint's health (position, current/load, temperature, voltage, torque, hardware
    error); reply: :class:`~spm_console.motion.servo_tools.ServoHealth`. Refused while moving."""

    id: int


@dataclass(frozen=True)
class Torque(Request["ServoHealth"]):
    """Torque Enable of one joint ("on": goal := present position first, so nothing
    lunges); reply: ServoHealth read after it. Refused while moving. Off: the wrist is no
    longer homed (the joint can be moved by hand)."""

    id: int
    joint: int
    """1-based."""
    on: bool


@dataclass(frozen=True)
class Reboot(Request["ServoHealth"]):
    """REBOOT one joint's servo (clears a latched hardware error; Protocol 2.0), wait until it
    answers; reply: ServoHealth read after it. Refused while moving. The servo comes back
    with torque off: the wrist is no longer homed."""

    id: int
    joint: int
    """1-based."""


@dataclass(frozen=True)
class Query(Request[BusReport]):
    """A bus diagnostic by servo id (:mod:`~spm_console.motion.servo_query`); reply: BusReport.
    Refused while moving."""

    id: int
    query: BusQuery


@dataclass(frozen=True)
class Home(Request["HomingResult"]):
    """Home the wrist; reply: HomingResult."""

    id: int


@dataclass(frozen=True)
class Execute(Request["ExecutionResult"]):
    """Execute a plan (after the runtime's verification; an approach move first when the
    wrist is farther than ``approach_tolerance_deg`` from its start); reply: ExecutionResult."""

    id: int
    plan: Plan
    approach_tolerance_deg: float | None = None
    skip_homing: str = ""
    """Empty: refused unless this process homed the wrist. Otherwise the operator's explicit
    override (why), written to the run log."""
    source: str | None = None
    """Where the plan came from (a file), for the run log."""
    approach: bool = True
    """False: no approach move; a wrist farther than the tolerance from the plan's start is
    refused (nothing moves, the run log says why)."""


@dataclass(frozen=True)
class Verify(Request["PlanCheck"]):
    """Verify a plan against this profile's workspace and the runtime's rules exactly as
    :class:`Execute` will, moving nothing (a front end asks before it homes the wrist for a
    plan from a file); reply: :class:`~spm_console.motion.plan_check.PlanCheck`, or a
    refusal (exit 26). Refused while moving."""

    id: int
    plan: Plan
    log_kind: str = ""
    """Non-empty: a refused plan also leaves a run folder of this kind (outcome ``refused``,
    nothing moved), as a refusal of :class:`Execute` does."""


@dataclass(frozen=True)
class Nudge(Request["NudgeResult | None"]):
    """Commissioning: move servos by id to small offsets from their rest (deg of their own
    counting, each within :data:`~spm_console.motion.nudge.BALL_DEG`), slowly and with their
    effort limited, the others holding (:mod:`~spm_console.motion.nudge`); reply:
    NudgeResult. ``release``: end the nudging instead (PWM Limits restored; torque off, or
    with ``hold`` on again holding where the servos are)."""

    id: int
    moves: tuple[tuple[int, float], ...] = ()
    speed_degps: float = 2.0
    release: bool = False
    hold: bool = False


@dataclass(frozen=True)
class Follow(Request["FollowOutcome"]):
    """Follow targets live (:mod:`~spm_console.motion.follow.loop`): a timed list, or live
    targets sent with :class:`SetTarget` from ``initial_deg`` on; reply: FollowOutcome."""

    id: int
    timed: TimedTargets | None = None
    initial_deg: tuple[float, float, float] | None = None
    deadman_s: float | None = None
    """Live targets: hold when none arrives for this long (None: never)."""
    skip_homing: str = ""
    source: str | None = None


@dataclass(frozen=True)
class SetTarget:
    """A new live target for the following under way (deg); ignored when none runs."""

    theta_deg: tuple[float, float, float]


@dataclass(frozen=True)
class EndFollow:
    """The live source is done: settle on the current target and end the run."""


@dataclass(frozen=True)
class EStop:
    """Stop the motion under way at once (the profile's stop action)."""

    reason: str
    sent_clock: float | None = None
    """``time.perf_counter()`` when the client sent it (CLOCK_MONOTONIC: the same clock in
    every process on Linux; the simulated clock in lockstep), so the log measures the E-stop
    from the client's request."""
    by_signal: bool = False
    """A terminating signal asked for it: with nothing moved yet, the run is an interruption
    (exit 130), not a stop (20)."""
    after: int = 0
    """Id of the last motion request whose result the client had when it sent this (0: none):
    the E-stop is for the motion under way or a later one. One that arrives after the motion
    it was meant for has ended stops nothing (and never stops the next one)."""


@dataclass(frozen=True)
class Heartbeat:
    """The client is alive (sent every HEARTBEAT_S during a motion)."""


@dataclass(frozen=True)
class Close:
    """Close the bus and end the process."""


#: Everything a front end sends: the requests answered, and the messages that are not.
ToServer = (Ping | ReadPosition | Status | Torque | Reboot | Query | Home | Execute | Verify
            | Follow | Nudge | SetTarget | EndFollow | EStop | Heartbeat | Close)


@dataclass(frozen=True)
class Reply(Generic[R]):
    id: int
    value: R
    homed: bool = False
    """Whether this motion process has the wrist homed, as of this answer (the one flag the
    front ends read)."""


@dataclass(frozen=True)
class Failed:
    """An operator-facing error: its message and exit code (an SpmError on the client)."""

    id: int
    message: str
    exit_code: int
    reason: str = ""
    """A :class:`~spm_console.refusals.Refusal` code when a precondition refused the request."""
    homed: bool = False
    """As :attr:`Reply.homed`."""


@dataclass(frozen=True)
class Planned:
    """The motion the runtime is about to run, as it built it and verified it (an approach
    or homing move included), sent before its first cycle: what a front end counts down."""

    duration_s: float
    """Every segment's samples together, s."""
    phases: tuple[str, ...]
    """The segments' phases in order ('homing', 'approach', 'plan')."""


@dataclass(frozen=True)
class Telemetry:
    """The loop's samples since the last message (one message per TELEMETRY_S at most)."""

    samples: tuple[Sample, ...]
    dropped: int = 0
    """Samples left out since the last message because the client read too slowly (the run
    log has them all)."""
