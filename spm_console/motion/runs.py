"""Homing and execution on an open bus: the one orchestration every front end reaches
(through the motion process for the console and scripts, directly for the CLI).

Each run creates its log, builds the executor (which verifies every segment against this
profile's workspace before torque-on) and hands it to ``attach`` so that an E-stop reaches
it from then on. Degrees, seconds.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TypedDict

import numpy as np

from spm_console.config.models import servo_limits_deg, servo_model_of
from spm_console.config.schema import Profile
from spm_console.core.plan import Plan
from spm_console.core.workspace.data import Workspace
from spm_console.devices.base import ServoBus
from spm_console.errors import BadInputError, PlanRefusedError, RefusedError, SpmError
from spm_console.formatting import fmt_deg
from spm_console.motion.executor import Executor
from spm_console.motion.goals.load_offsets import load_offsets, sent_references
from spm_console.motion.homing import HomingResult, home, plan_segments
from spm_console.motion.logs.mcap_log import mcap_beside
from spm_console.motion.logs.profile_record import wrist_digests
from spm_console.motion.logs.run_end import run_end
from spm_console.motion.logs.runlog import RunLog
from spm_console.motion.plan_check import PlanCheck, PlanVerifier
from spm_console.motion.plans import plan_summary
from spm_console.motion.sample import Sample
from spm_console.motion.segments import ExecutionResult, Segment
from spm_console.refusals import Refusal
from spm_console.system.simclock import SimClock, attached

SampleCallback = Callable[[Sample], None]
Attach = Callable[[Executor], None]


class Timing(TypedDict, total=False):
    """An executor's clock and period sleep, s (absent: the wall clock's)."""

    clock: Callable[[], float]
    sleep: Callable[[float], None]


@dataclass(frozen=True)
class RunContext:
    """Where a run happens: the one run-log metadata schema of every front end."""

    port: str
    """The serial port (the emulator's pty for the emulated bus)."""
    sim: bool
    """Emulated bus."""
    faults: tuple[str, ...] = ()
    """Faults injected into the emulated bus."""
    logs_root: str | None = None
    sim_clock: str | None = None
    """The emulated bus runs in simulated time on the clock at this path
    (:mod:`spm_console.system.simclock`); None: the wall clock."""
    preview: bool = False
    """A preview: the run the wrist is about to make, on its twin (said in the run logs)."""

    @property
    def bus_label(self) -> str:
        return "emulated bus" if self.sim else f"serial port {self.port}"

    def meta(self) -> dict[str, object]:
        return {"bus": self.bus_label, "port": self.port, "sim": self.sim,
                "faults": list(self.faults),
                "clock": "real" if self.sim_clock is None else "simulated",
                **({"preview": True} if self.preview else {})}

    def clock(self) -> SimClock | None:
        """The simulated clock of this run's bus (None: the wall clock)."""
        return None if self.sim_clock is None else attached(self.sim_clock)

    def mcap_writer(self, profile: Profile) -> Callable[[Path], object] | None:
        """What writes the run's MCAP beside its log once it has finished: none for a preview
        (a prediction, read through its samples; the MCAP's FK of every sample would take
        longer than the simulated run)."""
        return None if self.preview else mcap_beside(profile)

    def timing(self, live: bool = False) -> Timing:
        """The executor's ``clock`` and ``sleep`` (none: the wall clock's). ``live``: the run
        follows an operator's input as it comes, so simulated time runs no faster than
        real time (at the clock's own pace when it has one)."""
        sim = self.clock()
        if sim is None:
            return Timing()
        rate = (sim.rate or 1.0) if live else sim.rate
        return Timing(clock=sim.now, sleep=lambda dt: sim.sleep(dt, rate))


def _executor(profile: Profile, bus: ServoBus, ws: Workspace, kind: str,
              plans: Sequence[Mapping[str, object]], ctx: RunContext,
              on_sample: SampleCallback | None) -> Executor:
    log = RunLog.create(kind, profile.name, profile.digest(), plans, root=ctx.logs_root,
                        extra=ctx.meta(), wrist=wrist_digests(profile))
    log.on_finish = ctx.mcap_writer(profile)
    return Executor(profile, bus, workspace=ws, log=log, on_sample=on_sample, emulated=ctx.sim,
                    simulated_time=ctx.clock() is not None, **ctx.timing())


@contextlib.contextmanager
def refusals_logged(log: RunLog | None) -> Iterator[None]:
    """A refusal (any operator error before or instead of motion) closes ``log`` with its
    reason and exit code: outcome ``interrupted`` for a signal, ``refused`` otherwise."""
    try:
        yield
    except BaseException as exc:
        if log is not None and not log.finished:  # an internal error too: keep what we have
            end = run_end(exc)
            if isinstance(exc, SpmError):
                log.event(end.outcome, 0.0, message=end.message, exit_code=end.exit_code)
            log.finish(end.outcome, end.exit_code, end.message, {})
        raise


def refused_run(profile: Profile, kind: str, ctx: RunContext, exc: SpmError) -> None:
    """The run folder of a run refused before the runtime could start it (no bus, a signal
    while connecting): the same schema, outcome ``refused`` or ``interrupted``."""
    log = RunLog.create(kind, profile.name, profile.digest(), [], root=ctx.logs_root,
                        extra=ctx.meta(), wrist=wrist_digests(profile))
    log.on_finish = ctx.mcap_writer(profile)
    with contextlib.suppress(SpmError), refusals_logged(log):
        raise exc


def run_home(profile: Profile, bus: ServoBus, ws: Workspace, ctx: RunContext,
             on_sample: SampleCallback | None, attach: Attach) -> HomingResult:
    """Home the wrist (``home`` reads the pose and checks the assembly mode before anything
    moves); a refusal is logged too."""
    ex = _executor(profile, bus, ws, "home", [{"kind": "homing"}], ctx, on_sample)
    with refusals_logged(ex.log):
        attach(ex)
        return home(ex)


def run_execute(profile: Profile, bus: ServoBus, ws: Workspace, plan: Plan, ctx: RunContext,
                on_sample: SampleCallback | None, attach: Attach,
                approach_tolerance_deg: float | None = None, *, homed: bool,
                skip_homing: str = "", source: str | None = None,
                approach: bool = True) -> ExecutionResult:
    """Execute ``plan``, with a straight approach move to its start when the wrist is farther
    than the tolerance (default: the profile's ``safety.approach_tolerance_deg``); with
    ``approach`` False such a wrist is refused instead (BadInputError), nothing moved.

    The rule of every front end: the wrist was homed first (``homed``), or the operator
    overrode it explicitly (``skip_homing``: why; written to the run log)."""
    ex = _executor(profile, bus, ws, "execute", [plan_summary(plan, source)], ctx, on_sample)
    log = ex.log
    with refusals_logged(log):
        if log is not None:
            log.meta["homing"] = "done" if homed else f"skipped by the operator: {skip_homing}"
        if not homed and not skip_homing:
            raise RefusedError(Refusal.NOT_HOMED)
        theta0 = ex.read_initial()
        tol = (profile.safety.approach_tolerance_deg if approach_tolerance_deg is None
               else approach_tolerance_deg)
        segments = plan_segments(profile, theta0, plan, tol)
        if not approach and len(segments) > 1:
            raise BadInputError(f"the wrist is at θ = {fmt_deg(theta0)}, not at the plan's "
                                f"start {fmt_deg(plan.reference_deg[0])} (approach move disabled)")
        if log is not None:
            log.meta["plans"] = [plan_summary(s.plan, source if s.phase == "plan" else None)
                                 | {"phase": s.phase} for s in segments]
        attach(ex)
        return ex.run(segments, theta0_deg=theta0)


def verify_before_motion(profile: Profile, ws: Workspace, plan: Plan) -> PlanCheck:
    """The plan verified as :func:`run_execute` will verify it, before anything is powered: the
    runtime's rules against this profile's workspace (:mod:`~spm_console.motion.plan_check`)
    and the identified load's offsets along it from rest at its start. A front end asks this
    before it homes the wrist for a plan it did not solve; :class:`PlanRefusedError` (exit 26)
    says that nothing moved. The approach move, built from the pose measured after homing, is
    verified when the plan runs."""
    try:
        check = PlanVerifier(profile, ws).verify([Segment("plan", plan)])
        lo, hi = servo_limits_deg(profile)
        refs = np.clip(np.asarray(plan.reference_deg, float), lo, hi)
        sent_references(refs, load_offsets(profile, servo_model_of(profile), refs, refs[0]),
                        lo, hi, None)
    except PlanRefusedError as exc:
        raise PlanRefusedError(f"{exc.message}; nothing moved", exc.issue) from None
    return check
