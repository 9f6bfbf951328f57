"""Plans executed on the physical emulated wrist, before and after identifying its servos.

The physical wrist is MX-106 drives (firmware loop, PWM, DC motor, friction, gear play) on the
rigid-body closed chain. First the identification experiment runs on it (as ``identify --experiment``
does, with the speed bound of 250 °/s so its steps reach 9°) and the identified ``[servo]``
is put in the profile. Then each run is planned (the planner's own path: linear range and
tube included) and executed twice on a fresh physical wrist: with the paper's model (27),
p = 32.22 (the baseline column) and with the identified model and settling at the goal
(``[settle] duration_s = 1``: the runtime takes up the servo's offset at rest) (ours). For each: outcome,
tracking against the run's model (RMS, max), final error, how many measured samples lie
outside the grid's certified set P′, the largest excursion outside the plan's region (the
union of its route's regions) and the leg contacts the emulated wrist told (an independent
check of the workspace's link-interference model: any is a finding).
Runs: the paper's MVN and minimum-time pairs, then minimum time at 100, 150 and 200 °/s on the
minimum-time pair. The emulated wrist runs in a process of its own, as under ``--sim``.

Targets are the physical-servo issue's: after identification every run completes, no sample
outside P′, final error ≤ 0.2°, tracking RMS ≤ 0.15°; identification held-out RMS ≤ 0.1°
with ≤ 30 s of motion.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass

import numpy as np

from benchmarks.common import Row
from spm_console.config.load import load_profile
from spm_console.config.schema import Plant, Profile, Settle
from spm_console.core.plan import Plan
from spm_console.core.workspace.data import Workspace
from spm_console.devices.dynamixel.bus import open_bus
from spm_console.devices.emulator.child import EmulatorChild
from spm_console.errors import SpmError
from spm_console.motion.executor import Executor, Segment
from spm_console.motion.logs.runlog import RunLog
from spm_console.report import paper_values as pv
from spm_console.services.identify.experiment import (
    experiment_once,
    fit_experiment,
    identified_servo,
)
from spm_console.services.oneshot import RunRequest
from spm_console.services.plan_request import PlanRequest, plan_motion
from spm_console.store.workspace_cache import load_or_build

FAST_DEGPS = 250.0
"""The speed bound of the profile for the runs above the paper's 50 °/s."""


@dataclass
class Outcome:
    outcome: str
    rms_deg: float
    max_deg: float
    final_deg: float
    excursion_deg: float
    outside: int
    message: str
    contacts: int
    """Leg contacts the emulated wrist told during the run."""


def _execute(profile: Profile, ws: Workspace, plan: Plan) -> Outcome:
    """The plan on a fresh physical wrist in a process of its own."""
    certified = ws.certified_set()
    emu = EmulatorChild(profile, initial_deg=list(plan.reference_deg[0]))
    bus = open_bus(profile, emu.launch())
    with tempfile.TemporaryDirectory() as tmp:
        log = RunLog.create("bench", profile.name, profile.digest(), [], root=tmp)
        ex = Executor(profile, bus, workspace=ws, log=log)
        began = time.perf_counter()
        try:
            result = ex.run([Segment("plan", plan)])
            time.sleep(0.2)  # the emulator tells its contacts every 0.1 s
            contacts = len(emu.collisions(began, time.perf_counter()))
        finally:
            bus.close()
            emu.stop()
    ok = np.array([s.read_ok for s in ex.samples], bool)
    meas = np.array([s.measured_deg for s in ex.samples])[ok]
    err = np.abs(meas - np.array([s.predicted_deg for s in ex.samples])[ok])
    nan = float("nan")
    return Outcome(
        result.outcome,
        float(np.sqrt(np.mean(err ** 2))) if err.size else nan,
        float(err.max()) if err.size else nan,
        float(np.abs(meas[-1] - plan.reference_deg[-1]).max()) if meas.size else nan,
        float(np.min([r.violation_deg(meas) for r in plan.regions.regions], axis=0).max())
        if meas.size else nan,
        int((~certified.contains(meas)).sum()) if meas.size else 0,
        result.message, contacts)


def _rows(name: str, before: Outcome | SpmError, after: Outcome | SpmError) -> list[Row]:
    if isinstance(after, SpmError):
        return [Row(f"physical: {name}: planned", float("nan"), "", "a plan", passed=False,
                    note=f"refused after identification: {after.message[:200]}")]
    b = before if isinstance(before, Outcome) else None
    done = after.outcome == "completed"
    was = (f"before: {b.outcome}, max {b.max_deg:.3f}°" if b is not None else
           f"before: refused ({before.message[:120] if isinstance(before, SpmError) else ''})")
    return [
        Row(f"physical: {name}: tracking RMS", after.rms_deg, "°", "≤ 0.15°",
            None if b is None else b.rms_deg, done and after.rms_deg <= 0.15,
            note=f"outcome {after.outcome}; max {after.max_deg:.3f}°; {was}"
                 + ("" if done else f"; {after.message[:150]}")),
        Row(f"physical: {name}: final error", after.final_deg, "°", "≤ 0.2°",
            None if b is None else b.final_deg, done and after.final_deg <= 0.2),
        Row(f"physical: {name}: samples outside P′", after.outside, "", "0",
            None if b is None else b.outside, after.outside == 0,
            note=f"largest excursion outside the plan's region {after.excursion_deg:.3f}°"
                 + ("" if b is None else f" (before {b.excursion_deg:.3f}°)")
                 + f"; leg contacts in the emulated wrist {after.contacts}"
                 + ("" if b is None else f" (before {b.contacts})")),
    ]


def _run(profile: Profile, ws: Workspace, req: PlanRequest) -> Outcome | SpmError:
    try:
        plan = plan_motion(profile, ws, req).plan
    except SpmError as exc:
        return exc
    return _execute(profile, ws, plan)


def run() -> list[Row]:
    agile = load_profile("profiles/agile_wrist.toml").model_copy(
        update={"plant": Plant(model="physical")})
    ws, _ = load_or_build(agile)
    fast = agile.model_copy(update={"limits": agile.limits.model_copy(
        update={"vmax_degps": FAST_DEGPS})})
    rows: list[Row] = []
    with tempfile.TemporaryDirectory() as tmp:
        exp = experiment_once(fast, RunRequest(sim=True, log_root=tmp, handle_signals=False))
    if exp.t is None or exp.reference_deg is None or exp.measured_deg is None:
        return [Row("physical: identification", float("nan"), "", "completes", passed=False,
                    note=exp.execution.message)]
    fit = fit_experiment(agile, exp)
    servo = identified_servo(agile, fit, "benchmark")
    a = fit.assessment
    rows += [
        Row("physical: identification held-out RMS", a.held_out_rms_deg, "°", "≤ 0.1°",
            passed=a.held_out_rms_deg <= 0.1,
            note=f"ωn {servo.p:.2f} rad/s, ζ {servo.zeta:.3f}, delay {1e3 * servo.delay_s:.1f} "
                 f"ms, linear range {servo.linear_range_deg}° "
                 f"({'saturation seen' if a.saturated else 'never saturated'}), residual bound "
                 f"{servo.residual_bound_deg}°; held-out max {a.held_out_max_deg:.3f}°; load "
                 f"{servo.load_deg_per_nm} deg/(N·m) of holding torque, Coulomb "
                 f"{servo.coulomb_deg}°"
                 + ("" if fit.order is None else
                    f"; a third pole: held-out {fit.order.held_out_rms_3rd_deg:.3f}° against "
                    f"{fit.order.held_out_rms_2nd_deg:.3f}° ("
                    f"{'asks' if fit.order.asks else 'not asked'})")),
        Row("physical: identification motion", exp.excitation.duration_s, "s", "≤ 30 s",
            passed=exp.excitation.duration_s <= 30.0),
    ]
    cases = [("paper MVN", "mvn", pv.MVN_START_DEG, pv.MVN_STEPS, None),
             ("paper minimum time", "mintime", pv.MINTIME_START_DEG, 2, pv.MINTIME_VMAX_DEGPS)]
    cases += [(f"minimum time {v:g}°/s", "mintime", pv.MINTIME_START_DEG, 2, v)
              for v in (100.0, 150.0, 200.0)]
    for name, method, start, steps, vmax in cases:
        base = fast if vmax is not None and vmax > agile.limits.vmax_degps else agile
        after = base.model_copy(update={"servo": servo, "settle": Settle(duration_s=1.0)})
        req = PlanRequest(method, np.asarray(start, float), np.asarray(pv.MVN_GOAL_DEG, float),  # type: ignore[arg-type]
                          steps=steps, vmax_degps=vmax)
        rows += _rows(name, _run(base, ws, req), _run(after, ws, req))
    return rows
