"""Shared set-up of the executor integration tests: the paper's MVN plan, a run over the
pty emulator with our DynamixelBus, and the emulator's true velocity at each read."""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from spm_console.config.models import servo_model_of
from spm_console.config.schema import Profile
from spm_console.core.plan import Plan
from spm_console.core.planning.mvn import solve_mvn
from spm_console.core.polytope.region import Region
from spm_console.devices.dynamixel.bus import open_bus
from spm_console.devices.emulator.bus import EmulatorHandle, start_emulator
from spm_console.devices.emulator.faults import FaultSpec
from spm_console.motion.executor import ExecutionResult, Executor, Segment
from spm_console.motion.logs.runlog import RunLog
from spm_console.motion.sample import Sample
from spm_console.store.plan_file import plan_hash
from spm_console.system.simclock import SimClock
from tests.support.ws_helpers import agile_workspace

PAPER_START = np.array([127.53, 83.23, 85.25])
PAPER_GOAL = np.array([66.80, 155.00, 131.48])


@functools.lru_cache(maxsize=4)
def paper_mvn(profile: Profile, N: int = 150) -> Plan:
    """MVN (30) between the paper's start and goal, N = 150. Region: the 65..155° grid box
    (the workspace's P is not needed here: neither constraint set is active on this plan)."""
    r = solve_mvn(servo_model_of(profile), PAPER_START, PAPER_GOAL, N, Region.box(65.0, 155.0))
    return r.to_plan("mvn", profile_hash=plan_hash(profile))


@dataclass
class EmuRun:
    result: ExecutionResult
    executor: Executor
    emulator: EmulatorHandle
    samples: list[Sample]


def run_on_emulator(
    profile: Profile, segments: Sequence[Segment], tmp_path: Path,
    faults: Sequence[FaultSpec] = (), initial_deg: np.ndarray | None = None,
    on_sample: Callable[[Executor, EmulatorHandle, Sample], None] | None = None,
    after: Callable[[EmulatorHandle], None] | None = None,
    simulated: bool = True,
) -> EmuRun:
    """Execute over a fresh emulator; ``after`` runs before the emulator is stopped.
    ``simulated``: the loop, the bus and the emulator in lockstep on a simulated clock (else
    the wall clock: for the tests about real time)."""
    start = segments[0].plan.reference_deg[0] if initial_deg is None else initial_deg
    ws = agile_workspace()  # before the emulator's fault clock starts (a first build takes seconds)
    clock = SimClock.create() if simulated else None
    emu = start_emulator(profile, faults, record=True, initial_deg=list(start), sim=clock)
    bus = open_bus(profile, emu.port, sim=clock)
    timing: dict[str, Any] = {} if clock is None else {"clock": clock.now, "sleep": clock.sleep}
    try:
        log = RunLog.create("execute", profile.name, profile.digest(), [], root=tmp_path)
        holder: list[Executor] = []
        cb = None if on_sample is None else (lambda s: on_sample(holder[0], emu, s))
        ex = Executor(profile, bus, workspace=ws, log=log, on_start=emu.start_clock, on_sample=cb,
                      **timing)
        holder.append(ex)
        res = ex.run(list(segments))
        if after is not None:
            after(emu)
        return EmuRun(res, ex, emu, list(ex.samples))
    finally:
        bus.close()
        emu.stop()
        if clock is not None:
            clock.close()


def wait_emulated(emu: EmulatorHandle, seconds: float) -> None:
    """Let ``seconds`` pass for the emulated wrist: on its simulated clock when it has one
    (nothing moves otherwise), else on the wall clock."""
    if emu.sim is not None:
        emu.sim.sleep(seconds)
    else:
        time.sleep(seconds)


def true_velocity_at_reads(run: EmuRun) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(true position, true velocity, sample index) at the instant each position was read.

    The emulator records its exact state whenever it wakes, and marks the records that
    answered a read; the first such record after the cycle's good read was sent
    (``read_offset_s``, counted from the cycle's deadline) and before the cycle's bus work
    ended is the sync read that produced the measurement. (Not merely the window's last
    record: the emulator also wakes for other packets and its timers within the window,
    later when the host stalled it.)
    """
    tr = run.emulator.true_state()
    T = tr["t"] + run.emulator.t0
    pos, vel, idx = [], [], []
    for j, s in enumerate(run.samples):
        if not s.read_ok:
            continue
        sent = run.executor.t0 + s.k * run.executor.ts + s.read_offset_s  # offset from the deadline
        end = run.executor.t0 + s.t + s.bus_s  # t is the cycle's actual start, after any lateness
        hit = np.flatnonzero(tr["read"] & (sent <= T) & (end + 1e-6 >= T))
        if hit.size:
            pos.append(tr["position_deg"][hit[0]])
            vel.append(tr["velocity_degps"][hit[0]])
            idx.append(j)
    return np.array(pos), np.array(vel), np.array(idx, int)
