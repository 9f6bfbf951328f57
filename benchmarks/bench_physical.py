"""Plans executed on the physical emulated wrist (``[plant] model = "physical"``).

The planner's model is eq. (27) with the profile's p; the physical wrist is MX-106 drives
(firmware loop, PWM, DC motor, friction) on the rigid-body closed chain. For each plan:
outcome, tracking against the model (RMS, max), final error, and how many measured samples
lie outside the grid's certified set P′ (with the largest excursion outside the region the
plan was planned in). The emulated wrist runs in a process of its own, as under ``--sim``.
The runtime certifies plans near the boundary against a finer set than P′: the ideal
baseline shows how many samples of a run the runtime accepted lie outside P′ all the same.
Runs: the paper's MVN and minimum-time pairs, then minimum time at 100, 150 and 200 °/s on the
minimum-time pair (a profile whose planning limit allows them). Baseline: the same plan on
the ideal emulated wrist (eq. (27) itself), same run.

Targets are the physical-servo issue's, meant for after identification: every run completes,
no excursion, final error ≤ 0.2°, tracking RMS ≤ 0.15°. Until the planner uses an identified
servo model, rows that miss them say how far the plans are from what the servo does.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass

import numpy as np

from benchmarks.common import Row
from spm_console.config.load import load_profile
from spm_console.config.models import servo_limits_deg, servo_model_of
from spm_console.config.schema import Plant, Profile
from spm_console.core.plan import Plan
from spm_console.core.planning.mintime import solve_mintime
from spm_console.core.planning.mvn import solve_mvn
from spm_console.core.polytope.region import Region
from spm_console.core.regions.choice import choose_region, region_containing
from spm_console.devices.dynamixel.bus import open_bus
from spm_console.devices.emulator.child import EmulatorChild
from spm_console.errors import SpmError
from spm_console.motion.executor import Executor, Segment
from spm_console.motion.logs.runlog import RunLog
from spm_console.report import paper_values as pv
from spm_console.store.workspace_cache import load_or_build


@dataclass
class Outcome:
    outcome: str
    rms_deg: float
    max_deg: float
    final_deg: float
    excursion_deg: float
    outside: int
    message: str


def _execute(profile: Profile, plan: Plan, region: Region) -> Outcome:
    """The plan on a fresh emulated wrist in a process of its own (as ``--sim`` runs it: its
    physics shares no interpreter with the servo loop, which runs here)."""
    certified = load_or_build(profile)[0].certified_set()
    emu = EmulatorChild(profile, initial_deg=list(plan.reference_deg[0]))
    bus = open_bus(profile, emu.launch())
    with tempfile.TemporaryDirectory() as tmp:
        log = RunLog.create("bench", profile.name, profile.digest(), [], root=tmp)
        ex = Executor(profile, bus, workspace=load_or_build(profile)[0], log=log)
        try:
            result = ex.run([Segment("plan", plan)])
        finally:
            bus.close()
            emu.stop()
    meas = np.array([s.measured_deg for s in ex.samples])
    ok = np.isfinite(meas).all(axis=1)
    n = len(meas)
    err = np.abs(meas - plan.position_deg[:n])[ok]
    seen = meas[ok]
    return Outcome(
        result.outcome,
        float(np.sqrt(np.mean(err ** 2))) if err.size else float("nan"),
        float(err.max()) if err.size else float("nan"),
        float(np.abs(seen[-1] - plan.reference_deg[-1]).max()) if seen.size else float("nan"),
        float(region.violation_deg(seen).max()) if seen.size else float("nan"),
        int((~certified.contains(seen)).sum()),
        result.message,
    )


def _rows(name: str, profile: Profile, plan: Plan, region: Region) -> list[Row]:
    physical = profile.model_copy(update={"plant": Plant(model="physical")})
    ideal = profile.model_copy(update={"plant": Plant(model="ideal")})
    phy, base = _execute(physical, plan, region), _execute(ideal, plan, region)
    done = phy.outcome == "completed"
    return [
        Row(f"physical: {name}: tracking RMS", phy.rms_deg, "°", "≤ 0.15° (after identification)",
            base.rms_deg, done and phy.rms_deg <= 0.15,
            note=f"outcome {phy.outcome} (ideal: {base.outcome}); max {phy.max_deg:.3f}° "
                 f"(ideal {base.max_deg:.3f}°)" + ("" if done else f"; {phy.message[:150]}")),
        Row(f"physical: {name}: final error", phy.final_deg, "°", "≤ 0.2°", base.final_deg,
            done and phy.final_deg <= 0.2),
        Row(f"physical: {name}: samples outside P′", phy.outside, "", "0", base.outside,
            phy.outside == 0,
            note=f"largest excursion outside the plan's region {phy.excursion_deg:.3f}° "
                 f"(ideal {base.excursion_deg:.3f}°)"),
    ]


def _refused(name: str, exc: SpmError) -> list[Row]:
    return [Row(f"physical: {name}: planned", float("nan"), "", "a plan", passed=False,
                note=f"refused: {exc.message}")]


def run() -> list[Row]:
    agile = load_profile("profiles/agile_wrist.toml")
    ws, _ = load_or_build(agile)
    sm = servo_model_of(agile)
    rows: list[Row] = []
    start, goal = np.array(pv.MVN_START_DEG), np.array(pv.MVN_GOAL_DEG)
    region = region_containing(ws, start, goal)
    lo, hi = servo_limits_deg(agile)  # the references within the servo limits, as planned
    plan = solve_mvn(sm, start, goal, pv.MVN_STEPS, region, ref_lo_deg=lo,
                     ref_hi_deg=hi).to_plan("mvn", agile.digest())
    rows += _rows("paper MVN", agile, plan, region)
    fast = agile.model_copy(update={"limits": agile.limits.model_copy(update={"vmax_degps": 250.0})})
    start, goal = np.array(pv.MINTIME_START_DEG), np.array(pv.MINTIME_GOAL_DEG)
    region = choose_region(ws, start, goal).region
    for vmax in (pv.MINTIME_VMAX_DEGPS, 100.0, 150.0, 200.0):
        name = "paper minimum time" if vmax == pv.MINTIME_VMAX_DEGPS else f"minimum time {vmax:g}°/s"
        try:
            res = solve_mintime(sm, start, goal, region, vmax, ref_lo_deg=lo, ref_hi_deg=hi)
            rows += _rows(name, fast if vmax > agile.limits.vmax_degps else agile,
                          res.to_plan("mintime", agile.digest()), region)
        except SpmError as exc:
            rows += _refused(name, exc)
    return rows
