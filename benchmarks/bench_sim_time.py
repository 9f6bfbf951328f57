"""Simulated time: the paper's MVN on the emulated wrist in lockstep, against the wall clock.

Rows (the paper's MVN pair, N = 150, from its start, homing skipped):

* the servo loop, bus and emulated wrist in lockstep (:mod:`spm_console.system.simclock`):
  wall-clock seconds per simulated second of the run, on the ideal servos (in-process bus) and
  on the physical wrist (the emulator in its own process, as under ``--sim``); the baseline
  is the same run on the wall clock (1 s per s, plus its overruns). Target: ≥ 20× faster than
  real time (≤ 0.05 s per s);
* ``execute --preview``'s whole command (connect, verify, execute, margins) on the physical
  twin, wall time; the baseline is the same command run on the wall clock;
* the preview against a run of the same plan on the wall clock on the same twin: the largest
  difference in final position and in tracking RMS per joint (target ≤ 0.02°).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import Row
from spm_console.cli.common import with_plant
from spm_console.config.load import load_profile
from spm_console.config.schema import Profile
from spm_console.devices.dynamixel.bus import open_bus
from spm_console.devices.emulator.bus import start_emulator
from spm_console.devices.emulator.child import EmulatorChild
from spm_console.motion.executor import Executor, Segment
from spm_console.motion.logs.runlog import RunLog
from spm_console.services.oneshot import RunRequest, execute_once
from spm_console.services.preview import preview_execute
from spm_console.store.workspace_cache import load_or_build
from spm_console.system.simclock import SimClock
from tests.support.exec_helpers import PAPER_START, paper_mvn

TARGET_S_PER_S = 0.05


def _loop_run(profile: Profile, simulated: bool, logs: Path) -> tuple[float, float]:
    """(wall s, simulated s) of the paper's MVN executed from its start."""
    ws, _ = load_or_build(profile)
    plan = paper_mvn(profile)
    clock = SimClock.create() if simulated else None
    physical = profile.plant.model == "physical"
    child = EmulatorChild(profile, initial_deg=list(PAPER_START), sim=clock) if physical else None
    emu = None if physical else start_emulator(profile, record=False,
                                               initial_deg=list(PAPER_START), sim=clock)
    port = child.launch() if child is not None else emu.port  # type: ignore[union-attr]
    bus = open_bus(profile, port, sim=clock)
    try:
        log = RunLog.create("execute", profile.name, profile.digest(), [], root=logs)
        timing = {} if clock is None else {"clock": clock.now, "sleep": clock.sleep}
        ex = Executor(profile, bus, workspace=ws, log=log, **timing)  # type: ignore[arg-type]
        t0 = time.perf_counter()
        res = ex.run([Segment("plan", plan)])
        wall = time.perf_counter() - t0
        if not res.ok:
            raise RuntimeError(f"the run stopped: {res.message}")
        return wall, res.stats.duration_s
    finally:
        bus.close()
        if child is not None:
            child.stop()
        if emu is not None:
            emu.stop()
        if clock is not None:
            clock.close()


def _req(logs: Path, sim_time: bool) -> RunRequest:
    return RunRequest(sim=True, sim_start_deg=PAPER_START, skip_homing="benchmark",
                      log_root=logs, handle_signals=False, sim_time=sim_time)


def run() -> list[Row]:
    base = load_profile("profiles/agile_wrist.toml")
    rows: list[Row] = []
    with tempfile.TemporaryDirectory() as tmp:
        logs = Path(tmp)
        for plant in ("ideal", "physical"):
            profile = with_plant(base, plant)
            wall_sim, dur = _loop_run(profile, True, logs)
            wall_real, _ = _loop_run(profile, False, logs)
            per_s = wall_sim / dur
            rows.append(Row(f"sim time: paper MVN, {plant}, s per sim s", per_s, "s/s",
                            f"<= {TARGET_S_PER_S:g} (20x)", wall_real / dur,
                            per_s <= TARGET_S_PER_S,
                            note=f"{dur:.2f} s simulated in {wall_sim:.3f} s; "
                                 f"{1.0 / per_s:.0f}x faster than real time"))
        twin = with_plant(base, "physical")
        plan = paper_mvn(twin)
        execute_once(twin, plan, _req(logs, True))  # warms this process's imports and caches
        t0 = time.perf_counter()
        real = execute_once(twin, plan, _req(logs, False)).execution
        real_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        pv = preview_execute(twin, plan, _req(logs, False))
        preview_s = time.perf_counter() - t0
        ex = pv.run.execution
        rows.append(Row("preview: paper MVN, physical twin, command", preview_s, "s",
                        "<= 0.3 (run only)", real_s, None,
                        note=f"whole command (emulator and motion process start, verify, "
                             f"run, margins); the run itself: {ex.stats.duration_s:.2f} s "
                             "simulated"))
        if not (ex.ok and real.ok and ex.final_deg is not None and real.final_deg is not None):
            rows.append(Row("preview vs real-clock run", float("nan"), "deg", "<= 0.02",
                            passed=False, note=f"preview: {ex.message}; real: {real.message}"))
            return rows
        d_final = float(np.abs(np.asarray(ex.final_deg) - np.asarray(real.final_deg)).max())
        d_rms = float(np.abs(np.asarray(ex.stats.tracking_rms_per_joint_deg)
                             - np.asarray(real.stats.tracking_rms_per_joint_deg)).max())
        rows.append(Row("preview vs real-clock run: final position", d_final, "deg", "<= 0.02",
                        None, d_final <= 0.02))
        rows.append(Row("preview vs real-clock run: tracking RMS", d_rms, "deg", "<= 0.02",
                        None, d_rms <= 0.02,
                        note=f"RMS per joint, preview {np.round(ex.stats.tracking_rms_per_joint_deg, 3)}"
                             f", real {np.round(real.stats.tracking_rms_per_joint_deg, 3)}"))
    return rows
