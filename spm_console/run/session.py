"""One startup path for a run, shared by the CLI, the TUI and the tests (STYLE §3).

Opens the bus (a serial port, or an emulated bus started here on a pty), creates
the run log, builds the segments (an approach move to the plan's start when the
wrist is elsewhere) and runs the :class:`~spm_console.run.executor.Executor`.
A refusal before motion (bad plan, bus silent, pose not reachable) still leaves
a run folder whose outcome says why. Degrees and seconds.
"""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from spm_console.core.plan import Plan
from spm_console.devices.base import ServoBus
from spm_console.devices.bus import open_bus
from spm_console.devices.emulator import EmulatorHandle, start_emulator
from spm_console.devices.faults import FaultSpec
from spm_console.errors import BadInputError, InterruptedBySignalError, SpmError
from spm_console.profile import Profile
from spm_console.run.executor import ExecutionResult, Executor
from spm_console.run.homing import HomingResult, home, plan_segments
from spm_console.run.operator_runs import RunContext
from spm_console.run.plans import plan_summary
from spm_console.run.runlog import RunLog
from spm_console.run.sample import Sample
from spm_console.run.signals import stop_signals
from spm_console.workspace_cache import load_or_build

F = NDArray[np.float64]
T = TypeVar("T")


@dataclass
class BusSession:
    """An open bus and, for ``--sim``, the emulator serving it."""

    bus: ServoBus
    port: str
    emulator: EmulatorHandle | None

    @property
    def sim(self) -> bool:
        return self.emulator is not None


@contextlib.contextmanager
def open_session(
    profile: Profile,
    port: str | None = None,
    sim: bool = False,
    faults: Sequence[FaultSpec] = (),
    sim_start_deg: F | None = None,
    record: bool = False,
) -> Iterator[BusSession]:
    """The bus on ``port`` (default: the profile's), or an emulated bus with ``sim``.

    An empty port in the profile means the emulated bus (profile ``bus.port`` docs).
    Faults and a start pose are for the emulated bus only.
    """
    dev = port or profile.bus.port
    use_sim = sim or not dev
    if not use_sim and (faults or sim_start_deg is not None):
        raise BadInputError("--fault and --sim-start act on the emulated bus: add --sim")
    emu = None
    if use_sim:
        emu = start_emulator(profile, faults, record=record,
                             initial_deg=None if sim_start_deg is None else list(sim_start_deg))
        dev = emu.port
    try:
        bus = open_bus(profile, dev)
        try:
            yield BusSession(bus=bus, port=dev, emulator=emu)
        finally:
            bus.close()
    finally:
        if emu is not None:
            emu.stop()


class SignalStop:
    """What a terminating signal does to a run (:mod:`spm_console.run.signals`).

    Once the executor exists the signal is an E-stop (the stop action, the log closed
    with outcome ``stopped``, exit 20). Before that it is only noted, and
    :meth:`check` refuses the run at the next step (nothing moved, exit 130): no
    exception is ever raised from inside the signal handler.
    """

    def __init__(self) -> None:
        self.executor: Executor | None = None
        self.pending: signal.Signals | None = None

    def __call__(self, sig: signal.Signals) -> None:
        if self.executor is not None:
            self.executor.request_estop(f"signal {sig.name}")
        elif self.pending is None:
            self.pending = sig

    def attach(self, executor: Executor) -> None:
        """From now on a signal E-stops ``executor``; refuse now if one came before."""
        self.check()
        self.executor = executor

    def check(self) -> None:
        if self.pending is not None:
            raise InterruptedBySignalError(
                f"interrupted by {self.pending.name} before any motion; nothing moved")


@dataclass
class RunRequest:
    """Where and how to run (the CLI's options)."""

    port: str | None = None
    sim: bool = False
    faults: Sequence[FaultSpec] = ()
    sim_start_deg: F | None = None
    approach: bool = True
    """Move to the plan's start first when the wrist is elsewhere."""
    log_root: str | Path | None = None
    cache_dir: str | Path | None = None
    """Workspace cache folder (default: ``$SPM_CONSOLE_CACHE`` or ``~/.cache/spm_console``)."""
    on_sample: Callable[[Sample], None] | None = None
    on_executor: Callable[[Executor], None] | None = None
    """Called with the executor before it runs (to wire an E-stop button)."""
    handle_signals: bool = True
    """Turn SIGINT/SIGTERM/SIGHUP/SIGQUIT into an E-stop (main thread only)."""


def _session(profile: Profile, kind: str, plans: list[dict[str, Any]], req: RunRequest,
             body: Callable[[Executor, BusSession], T]) -> T:
    on_signal = SignalStop()
    with stop_signals(on_signal) if req.handle_signals else contextlib.nullcontext():
        sim = req.sim or not (req.port or profile.bus.port)
        ctx = RunContext(req.port or profile.bus.port or "", sim, tuple(str(f) for f in req.faults),
                         None if req.log_root is None else str(req.log_root))
        log = RunLog.create(kind, profile.name, profile.digest(), plans, root=ctx.logs_root,
                            extra=ctx.meta())
        try:
            ws, _ = load_or_build(profile, cache_dir=req.cache_dir)
            with open_session(profile, req.port, req.sim, req.faults, req.sim_start_deg) as ses:
                log.meta["port"] = ses.port
                on_start = ses.emulator.start_clock if ses.emulator is not None else None
                ex = Executor(profile, ses.bus, workspace=ws, log=log, on_sample=req.on_sample,
                              on_start=on_start)
                if req.on_executor is not None:
                    req.on_executor(ex)
                on_signal.attach(ex)
                return body(ex, ses)
        except SpmError as exc:
            if not log.finished:
                outcome = "interrupted" if isinstance(exc, InterruptedBySignalError) else "refused"
                log.event(outcome, 0.0, message=exc.message, exit_code=int(exc.exit_code))
                log.finish(outcome, int(exc.exit_code), exc.message, {})
            raise
        finally:
            if not log.finished:  # an internal error escaped: keep what we have
                log.finish("error", 1, "internal error (see stderr)", {})


def execute_plan(profile: Profile, plan: Plan, req: RunRequest,
                 source: str | None = None) -> ExecutionResult:
    """Execute ``plan`` (adding an approach move when needed); the run log is written."""
    if req.sim and req.sim_start_deg is None:
        req = RunRequest(**{**req.__dict__, "sim_start_deg": plan.reference_deg[0]})

    def body(ex: Executor, _ses: BusSession) -> ExecutionResult:
        theta0 = ex.read_initial()
        start = plan.reference_deg[0]
        segments = plan_segments(profile, theta0, plan, profile.safety.approach_tolerance_deg)
        if len(segments) > 1 and not req.approach:
            raise BadInputError(
                f"the wrist is at θ = {np.round(theta0, 2).tolist()}°, not at the plan's "
                f"start {np.round(start, 2).tolist()}° (approach move disabled)")
        if ex.log is not None:
            ex.log.meta["plans"] = [plan_summary(s.plan, source if s.phase == "plan" else None)
                                    | {"phase": s.phase} for s in segments]
        return ex.run(segments, theta0_deg=theta0)

    return _session(profile, "execute", [plan_summary(plan, source)], req, body)


def run_homing(profile: Profile, req: RunRequest) -> HomingResult:
    """Home the wrist (see :mod:`spm_console.run.homing`); the run log is written."""
    return _session(profile, "home", [], req, lambda ex, _ses: home(ex))
