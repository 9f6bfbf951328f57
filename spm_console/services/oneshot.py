"""One-shot runs for the CLI (``home``, ``execute``) and ``reproduce``: connect, home, execute,
disconnect — through the operator runtime (:class:`~spm_console.services.session.Session`), so the
servo loop runs in the motion process and the emulated bus in its own process, under the same
rules as the console and scripts.

* **Homed first.** ``execute`` homes the wrist in the same session before the plan (its own
  run folder, kind ``home``), unless the operator overrides it with a reason
  (``skip_homing``, written to the execute run's log).
* **One signal path.** SIGINT/SIGTERM/SIGHUP/SIGQUIT E-stop the motion under way (exit 20);
  before any motion they refuse the run (exit 130, nothing moved).
* **Refusals leave a run folder.** A run refused before the runtime could start it (bus
  unreachable, a signal while connecting) gets a run folder with outcome
  ``refused``/``interrupted``, like the runtime's own refusals (a plan it refuses, or
  ``--no-approach`` with the wrist elsewhere).

The emulated servos power on at the profile's home, or at ``sim_start_deg``. Degrees, seconds.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

import numpy as np
from numpy.typing import NDArray

from spm_console.config.schema import Profile
from spm_console.core.plan import Plan
from spm_console.core.planning.follow.timed import TimedTargets
from spm_console.devices.emulator.faults import FaultSpec
from spm_console.errors import InterruptedBySignalError, OptionConflictError, SpmError
from spm_console.formatting import fmt_deg
from spm_console.motion.homing import HomingResult
from spm_console.motion.runs import RunContext, refused_run
from spm_console.motion.sample import Sample
from spm_console.motion.segments import ExecutionResult
from spm_console.services.session import Session
from spm_console.system.signals import stop_signals

if TYPE_CHECKING:  # the follower loads its QP solver and scipy (about 1 s): not for execute
    from spm_console.motion.follow.run import FollowOutcome

F = NDArray[np.float64]
T = TypeVar("T")


@dataclass
class RunRequest:
    """Where and how to run (the CLI's options)."""

    port: str | None = None
    sim: bool = False
    faults: Sequence[FaultSpec] = ()
    sim_start_deg: F | None = None
    """Power-on pose of the emulated servos, deg (default: the profile's home)."""
    approach: bool = True
    """Move to the plan's start first when the wrist is elsewhere."""
    skip_homing: str = ""
    """Empty: home first. Otherwise the operator's reason to execute without homing (logged)."""
    log_root: str | Path | None = None
    cache_dir: str | Path | None = None
    """Workspace cache folder (default: ``$SPM_CONSOLE_CACHE`` or ``~/.cache/spm_console``)."""
    on_sample: Callable[[Sample], None] | None = None
    on_connected: Callable[[Session], None] | None = None
    """Called once the motion process serves the bus (before any motion)."""
    handle_signals: bool = True
    """Turn SIGINT/SIGTERM/SIGHUP/SIGQUIT into an E-stop (main thread only)."""
    on_late_signal: Callable[[str], None] | None = None
    """Told the signal's name when one arrived after the motion had ended (nothing to stop;
    the run's result stands)."""
    sim_time: bool | None = None
    """The emulated bus in simulated time (None: as the environment or profile says)."""
    preview: bool = False
    """A preview on the wrist's twin (the run logs say so)."""
    lost_signal: Callable[[], signal.Signals | None] | None = None
    """A signal that came before the run's own handling and whose interrupt was lost (a
    library caught it): the run is refused as interrupted (the CLI's start-up record)."""

    def emulated(self, profile: Profile) -> bool:
        """Whether the run drives the emulated bus: ``--sim``, or no port given here or in the
        profile."""
        return self.sim or not (self.port or profile.bus.port)


@dataclass(frozen=True)
class OneShotResult:
    """An ``execute``: the homing run (None when skipped) and the execution (the homing's
    own result when homing stopped, in which case nothing else moved)."""

    execution: ExecutionResult
    homing: HomingResult | None


class _SignalStop:
    """A terminating signal: an E-stop of the motion under way, or (none yet) a refusal of the
    next one at :meth:`check` — nothing is raised inside the handler."""

    def __init__(self, session: Session) -> None:
        self.session = session
        self.pending: signal.Signals | None = None
        self.stopped_motion = False
        """A signal E-stopped a motion (else one that came after the last motion is late)."""

    def __call__(self, sig: signal.Signals) -> None:
        self.pending = self.pending or sig
        if self.session.estop(f"signal {sig.name}", by_signal=True):
            self.stopped_motion = True

    def check(self) -> None:
        if self.pending is not None:
            raise InterruptedBySignalError(
                f"interrupted by {self.pending.name} before any motion; nothing moved")


def run_context(profile: Profile, req: RunRequest) -> RunContext:
    sim = req.emulated(profile)
    return RunContext(req.port or profile.bus.port or "", sim, tuple(str(f) for f in req.faults),
                      None if req.log_root is None else str(req.log_root), preview=req.preview)


def one_shot(profile: Profile, kind: str, req: RunRequest, body: Callable[[Session], T]) -> T:
    sim = req.emulated(profile)
    if not sim and (req.faults or req.sim_start_deg is not None):
        raise OptionConflictError("--fault and --sim-start act on the emulated bus: add --sim")
    session = Session(profile, port=req.port, sim=sim,
                      logs_root=None if req.log_root is None else Path(req.log_root),
                      cache_dir=None if req.cache_dir is None else Path(req.cache_dir),
                      faults=req.faults, emulator_process=True,
                      initial_deg=None if req.sim_start_deg is None else list(req.sim_start_deg),
                      sim_time=req.sim_time, preview=req.preview)
    on_signal = _SignalStop(session)
    session.before_motion = on_signal.check
    with stop_signals(on_signal) if req.handle_signals else contextlib.nullcontext():
        lost = req.lost_signal() if req.lost_signal is not None else None
        if lost is not None:
            on_signal.pending = on_signal.pending or lost
        try:
            try:
                on_signal.check()
                session.connect()
                on_signal.check()
                if req.on_connected is not None:
                    req.on_connected(session)
            except SpmError as exc:
                refused_run(profile, kind, run_context(profile, req), exc)
                raise
            try:
                result = body(session)
            except InterruptedBySignalError as exc:  # refused before the runtime saw a request
                refused_run(profile, kind, run_context(profile, req), exc)
                raise
            late = on_signal.pending is not None and not on_signal.stopped_motion
            if late and on_signal.pending is not None and req.on_late_signal is not None:
                req.on_late_signal(on_signal.pending.name)
            return result
        finally:
            session.close()


def home_first(session: Session, req: RunRequest) -> HomingResult | None:
    """Home the wrist unless the operator overrode it (``req.skip_homing``); the result."""
    if req.skip_homing:
        return None
    session.home(req.on_sample)
    assert session.homing is not None
    return session.homing


def execute_once(profile: Profile, plan: Plan, req: RunRequest,
                 source: str | None = None) -> OneShotResult:
    """Home (unless overridden), then execute ``plan`` with an approach move when needed."""

    def body(session: Session) -> OneShotResult:
        # nothing is powered for a plan the runtime would refuse (it logs the refusal)
        session.verify(plan, log_kind="execute")
        homing = home_first(session, req)
        if homing is not None and not homing.execution.ok:
            return OneShotResult(homing.execution, homing)
        try:
            result = session.execute(plan, req.on_sample, skip_homing=req.skip_homing,
                                     source=source, approach=req.approach)
        except SpmError as exc:
            raise _after_homing(exc, homing) from None
        return OneShotResult(result, homing)

    return one_shot(profile, "execute", req, body)


def _after_homing(exc: SpmError, homing: HomingResult | None) -> SpmError:
    """A refusal of the plan after this run homed the wrist, saying truthfully what moved: the
    homing move, and where it ended (the runtime's refusal speaks of the plan's run only)."""
    if homing is None or homing.execution.final_deg is None:
        return exc
    where = f"the homing move ran and ended at θ = {fmt_deg(homing.execution.final_deg)}"
    if "; nothing moved" in exc.message:
        exc.message = exc.message.replace("; nothing moved", f"; nothing moved after homing ({where})")
    else:
        exc.message = f"{exc.message} ({where})"
    exc.args = (exc.message,)
    return exc


def home_once(profile: Profile, req: RunRequest) -> HomingResult:
    """Home the wrist (see :mod:`spm_console.motion.homing`); the run log is written."""

    def body(session: Session) -> HomingResult:
        session.home(req.on_sample)
        assert session.homing is not None
        return session.homing

    return one_shot(profile, "home", req, body)


def follow_once(profile: Profile, req: RunRequest, timed: TimedTargets | None = None,
                deadman_s: float | None = None,
                live_source: Callable[[Session], None] | None = None,
                source: str | None = None) -> FollowOneShot:
    """Home (unless overridden), then follow ``timed`` targets, or live targets that
    ``live_source(session)`` sends (from its own thread, once the following runs) with
    ``session.following.set_target`` until ``session.following.end_follow``; the live run
    starts holding the wrist's position."""

    def body(session: Session) -> FollowOneShot:
        homing = home_first(session, req)
        if homing is not None and not homing.execution.ok:
            return FollowOneShot(None, homing)
        initial = None if timed is not None else session.read_position()
        feeder = None
        if live_source is not None:
            def feed() -> None:
                while not session.moving.is_set():  # the following has begun
                    if done.wait(0.01):
                        return
                live_source(session)

            done = threading.Event()
            feeder = threading.Thread(target=feed, daemon=True, name="spm-follow-source")
            feeder.start()
        try:
            out = session.following.follow(timed, initial, deadman_s, req.on_sample,
                                           skip_homing=req.skip_homing, source=source)
        finally:
            if feeder is not None:
                done.set()
        return FollowOneShot(out, homing)

    return one_shot(profile, "follow", req, body)


@dataclass(frozen=True)
class FollowOneShot:
    """A ``follow``: the homing run (None when skipped) and the following (None when homing
    stopped, in which case nothing else moved)."""

    follow: FollowOutcome | None
    homing: HomingResult | None
