"""``identify --experiment``: home, run the identification excitation, fit the servo as it is.

The excitation (:mod:`spm_console.core.servo.experiment`) is sized to what the runtime will
accept with the profile's present model: its largest step keeps the model's speed at
:data:`SPEED_SHARE` of the profile's bound and below the 10° step rule, and its ramps and
chirp run at that share of the bound. When the runtime's verification refuses it (the
excursion leaves the certified set near the edge of the workspace), the amplitude shrinks by
:data:`SHRINK` until it passes, at most :data:`MAX_TRIES` times. Then it runs like any plan:
homed first (identification never skips homing), verified by the motion process, logged, and
stopped by the same signals. The fit reads the run's own log.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from pydantic import ValidationError

from spm_console.config.checks import PTS_MAX, PTS_MIN
from spm_console.config.models import servo_model_of
from spm_console.config.schema import Identified, Profile, Servo
from spm_console.config.servo_section import with_servo
from spm_console.core.plan import Plan
from spm_console.core.plan_rules import MAX_REFERENCE_STEP_DEG
from spm_console.core.servo.experiment import Excitation, ExperimentFit, excitation, fit_record
from spm_console.core.workspace.data import Workspace
from spm_console.description.weight import holding_torque_nm
from spm_console.errors import BadInputError, PlanRefusedError, ProfileError, RefusedError, SolverError
from spm_console.motion.homing import HomingResult
from spm_console.motion.logs.runlog import load_run
from spm_console.motion.plan_check import verify_plan
from spm_console.motion.plans import plan_from_references
from spm_console.motion.segments import ExecutionResult
from spm_console.refusals import Refusal
from spm_console.services.oneshot import RunRequest, home_first, one_shot
from spm_console.services.session import SampleCallback, Session
from spm_console.store.workspace_cache import load_or_build

F = NDArray[np.float64]

SPEED_SHARE = 0.85
"""Share of the profile's speed bound the excitation may ask of the model."""
STEP_MARGIN_DEG = 1.0
"""The largest step stays this far below the runtime's step rule, deg."""
SHRINK = 0.7
"""Amplitude factor after a refusal."""
MAX_TRIES = 6
"""Excitations tried before the refusal is the answer."""
LOST_SHARE_MAX = 0.01
"""Most samples of the record whose reply was lost before the fit refuses it."""


@dataclass(frozen=True)
class ExperimentRun:
    """The homing, the experiment's execution, and its record (None when it did not
    complete)."""

    homing: HomingResult | None
    execution: ExecutionResult
    excitation: Excitation
    t: F | None = None
    """(n,) sample instants, s."""
    reference_deg: F | None = None
    """(n, 3) references as sent, deg."""
    measured_deg: F | None = None
    """(n, 3) positions read, deg."""


def experiment_plan(profile: Profile, cache_dir: Path | None = None,
                    workspace: Workspace | None = None) -> tuple[Excitation, Plan]:
    """The largest excitation about the home pose the runtime accepts (PlanRefusedError with
    the last refusal when none of :data:`MAX_TRIES` does), verified against ``workspace``
    (default: the profile's, from the cache)."""
    ws = workspace if workspace is not None else load_or_build(profile, cache_dir)[0]
    vmax = profile.limits.vmax_degps
    per_deg = servo_model_of(profile).dynamics.step_peak_speed()
    step = min(MAX_REFERENCE_STEP_DEG - STEP_MARGIN_DEG, SPEED_SHARE * vmax / per_deg)
    centre = np.asarray(profile.home.theta_deg, float)
    last: PlanRefusedError | None = None
    for _ in range(MAX_TRIES):
        ex = excitation(centre, profile.servo.ts_s, step, SPEED_SHARE * vmax)
        plan = plan_from_references(profile, ex.reference_deg, "experiment",
                                    notes={"step_deg": step, "speed_degps": SPEED_SHARE * vmax})
        try:
            verify_plan(profile, ws, plan)
            return ex, plan
        except PlanRefusedError as exc:
            last = exc
            step *= SHRINK
    assert last is not None
    raise PlanRefusedError(f"no identification experiment about home passes the runtime's "
                           f"verification (largest step tried down to {step / SHRINK:.2g}°): "
                           f"{last.message}", last.issue)


def experiment_once(profile: Profile, req: RunRequest) -> ExperimentRun:
    """Home, then execute the experiment; its record read back from the run's log."""
    if req.skip_homing:
        raise BadInputError("identification homes the wrist first: it cannot skip homing")
    ex, plan = experiment_plan(profile, None if req.cache_dir is None else Path(req.cache_dir))

    def body(session: Session) -> ExperimentRun:
        homing = home_first(session, req)
        assert homing is not None
        if not homing.execution.ok:
            return ExperimentRun(homing, homing.execution, ex)
        return _execute(session, ex, plan, req.on_sample, homing)

    return one_shot(profile, "identify", req, body)


def experiment_in_session(session: Session, on_sample: SampleCallback | None = None
                          ) -> ExperimentRun:
    """The experiment on the console's connected session: refused unless the wrist is homed
    (the session's plan, if any, is left as it was; its workspace is loaded, if it was not,
    and kept)."""
    if not session.homed:
        raise RefusedError(Refusal.NOT_HOMED)
    ex, plan = experiment_plan(session.profile, session.cache_dir, session.wrist.ensure_workspace())
    return _execute(session, ex, plan, on_sample, None)


def _execute(session: Session, ex: Excitation, plan: Plan, on_sample: SampleCallback | None,
             homing: HomingResult | None) -> ExperimentRun:
    result = session.execute(plan, on_sample, source="identification experiment")
    if not result.ok or result.log_dir is None:
        return ExperimentRun(homing, result, ex)
    t, ref, meas = _record(Path(result.log_dir), len(plan.reference_deg))
    return ExperimentRun(homing, result, ex, t, ref, meas)


def _record(run_dir: Path, n: int) -> tuple[F, F, F]:
    """The experiment's samples (its plan phase) from its run log: t (s), θ* and θ (deg; NaN
    where the reply was lost, up to :data:`LOST_SHARE_MAX` of the record, beyond which the
    record is refused)."""
    run = load_run(run_dir)
    rows = np.array([p == "plan" for p in run.phase])
    t = run.columns["t"][rows]
    ref, meas = run.vec("ref")[rows], run.vec("meas")[rows]
    if len(t) != n:
        raise BadInputError(f"{run_dir}: the log holds {len(t)} samples of the experiment, "
                            f"its plan {n}: not a complete record")
    ok = np.isfinite(meas).all(axis=1)
    if (~ok).mean() > LOST_SHARE_MAX:
        raise BadInputError(f"{run_dir}: {int((~ok).sum())} of {n} replies were lost, more "
                            f"than {100 * LOST_SHARE_MAX:g} %: repeat the experiment")
    return t, ref, meas


def fit_experiment(profile: Profile, run: ExperimentRun) -> ExperimentFit:
    """The experiment's record fitted with the load (:func:`fit_record`): the weight's
    holding torque at the poses read (the reference's where a reply was lost), from the
    profile's mass model. Raises BadInputError / SolverError as the fit does."""
    if run.t is None or run.reference_deg is None or run.measured_deg is None:
        raise BadInputError("the experiment did not complete: nothing to fit")
    meas, ref = run.measured_deg, run.reference_deg
    seen = np.asarray(np.isfinite(meas).all(axis=1), bool)
    poses = np.where(seen[:, None], meas, ref)
    try:
        hold = holding_torque_nm(profile, poses)
    except ValueError as exc:
        raise SolverError(f"the weight's load along the record: {exc}") from None
    return fit_record(run.excitation, run.t, ref, meas, hold)


def identified_servo(profile: Profile, fit: ExperimentFit, source: str) -> Servo:
    """The identified ``[servo]`` section of ``fit`` (Ts and discretization kept), its
    provenance naming ``source`` and the time now (UTC)."""
    s, a = fit.shared, fit.assessment
    # a load below the written precision is none (rounded to 0 it is no valid value)
    load = None if fit.load is None else round(float(fit.load.moments_deg[0]), 4)
    try:
        return Servo(
            p=round(s.p, 4), ts_s=profile.servo.ts_s, discretization=profile.servo.discretization,
            zeta=round(s.zeta, 4), delay_s=round(min(s.delay_s, 0.999 * profile.servo.ts_s), 6),
            linear_range_deg=round(max(a.linear_range_deg, 0.01), 2),
            residual_bound_deg=max(fit.residual_bound_deg, 0.01),
            load_deg_per_nm=None if load is None or load <= 0.0 else load,
            coulomb_deg=None if fit.load is None else round(fit.load.coulomb_deg, 4),
            identified=Identified(
                date=dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
                source=source[:500], samples=s.samples * s.joints,
                fit_rms_deg=round(a.fit_rms_deg, 4),
                held_out_rms_deg=round(a.held_out_rms_deg, 4),
                held_out_max_deg=round(a.held_out_max_deg, 4)))
    except ValidationError as exc:  # e.g. a model error above the 10° a profile accepts
        raise SolverError("the identified model does not make a valid [servo] section: "
                          + "; ".join(f"{'.'.join(map(str, e['loc']))}: {e['msg']}"
                                      for e in exc.errors())) from None


def identified_profile(text: str, servo: Servo, source: str) -> tuple[str, Profile]:
    """``text`` (the profile's TOML) with the identified ``[servo]``, and the profile it
    parses to; a model no profile can hold is a SolverError naming what is out of range."""
    ts = servo.ts_s
    if not PTS_MIN <= servo.p * ts <= PTS_MAX:
        raise SolverError(f"fitted ωn = {servo.p:.4g} rad/s gives ωn·Ts = {servo.p * ts:.4g}, "
                          f"outside the [{PTS_MIN:g}, {PTS_MAX:g}] a profile accepts")
    try:
        return with_servo(text, servo, source)
    except ProfileError as exc:
        raise SolverError(f"the identified model does not make a valid profile: {exc.message}") \
            from None
