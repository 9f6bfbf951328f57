"""A preview: the run the wrist is about to make, made first on its twin in simulated time.

:func:`preview_execute` reads where the wrist rests (the real bus, through the motion process;
the emulated bus's power-on pose with ``--sim``), then runs the whole ``execute`` (homing,
approach, the plan, settling) on the emulated wrist powered on there, in simulated time
(:mod:`spm_console.system.simclock`): the same runtime, bus protocol and checks, only time is
virtual, so it takes a fraction of the motion's duration and gives the same result every
time. The twin is the profile's: its ``[plant]`` (the physical wrist unless the profile or the
caller names the ideal servos), ``[servo]`` and geometry (as commissioned).

What it predicts (:class:`Preview`): the outcome and its exit code, per-joint tracking of the
servo model (RMS and largest, deg), the final error against the plan's goal (deg), the
closest approach to the edge of the grid's certified set P′ (L∞, deg;
:mod:`spm_console.core.workspace.margin`) and between the links of different legs (mm), over
the plan's own samples. The run logs are marked ``preview``. Degrees, mm, seconds.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import link_model_of, model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.model import platform_axes
from spm_console.core.plan import Plan
from spm_console.core.planning.follow.timed import TimedTargets
from spm_console.core.workspace.margin import certified_margin_deg
from spm_console.errors import BadInputError
from spm_console.motion.logs.mcap_log import platform_rotations
from spm_console.motion.logs.runlog import RunData, load_run
from spm_console.motion.segments import ExecutionResult
from spm_console.services.oneshot import (
    FollowOneShot,
    OneShotResult,
    RunRequest,
    execute_once,
    follow_once,
    one_shot,
)
from spm_console.services.session import Session
from spm_console.store.workspace_cache import load_or_build

F = NDArray[np.float64]

#: The phases whose samples the prediction's margins cover (homing and the approach are
#: runtime-built straight moves, checked on their own path; a following's periods are
#: ``follow``).
PLAN_PHASES = ("plan", "settle", "follow")


@dataclass(frozen=True)
class Preview:
    """The predicted run (see the module docstring)."""

    run: OneShotResult
    """The twin's runs: homing (None when skipped) and the execution, with their logs."""
    start_deg: F | None
    """Where the twin powered on: the wrist's measured rest, deg (None: the emulated bus's)."""
    plant: str
    """The twin's wrist: ``physical`` or ``ideal``."""
    final_error_deg: F | None
    """Final measured θ − the plan's goal, deg (None: no final reading)."""
    min_margin_deg: float
    """Closest approach to the edge of P′ over the plan's samples, L∞ deg (NaN: none)."""
    min_link_mm: float
    """Closest distance between links of different legs over the plan's samples, mm."""
    link_limit_mm: float
    """The profile's 2δ, mm."""
    simulated_s: float
    """Simulated time the twin's runs covered, s."""
    wall_s: float
    """Wall-clock time the preview took, s."""
    peak_current_a: F | None = None
    """Each motor's largest winding current over the twin's runs, A (None: the ideal servos'
    twin, which models no current)."""
    track: PredictedTrack | None = None
    """The execution's samples: planned θ* and predicted θ (None: no log)."""
    plan: Plan | None = None
    """The plan previewed (None: a following)."""


@dataclass(frozen=True)
class PredictedTrack:
    """The twin's execution sample by sample (approach, plan, settling), for a plot."""

    t_s: F
    """Time since the run began, s (K,)."""
    planned_deg: F
    """The reference θ* the loop sent, deg (K, 3)."""
    predicted_deg: F
    """The twin's measured θ, deg (K, 3; NaN where a read failed)."""


def rest_pose(profile: Profile, req: RunRequest) -> F | None:
    """Where the wrist rests: read on the real bus (one connection, nothing moves); on the
    emulated bus its power-on pose (``req.sim_start_deg``, None: the profile's home)."""
    if req.emulated(profile):
        return None if req.sim_start_deg is None else np.asarray(req.sim_start_deg, float)
    read = RunRequest(port=req.port, log_root=req.log_root, cache_dir=req.cache_dir,
                      handle_signals=req.handle_signals)
    return np.asarray(one_shot(profile, "preview", read, lambda s: s.read_position()), float)


def _twin_request(twin: Profile, req: RunRequest,
                  start: F | None = None) -> tuple[F | None, RunRequest]:
    """Where the wrist rests (``start``, else read), and the request that runs ``req``'s
    command on the twin powered on there, in simulated time, logged as a preview."""
    if start is None:
        start = rest_pose(twin, req)
    return start, RunRequest(sim=True, sim_start_deg=start, faults=req.faults,
                             approach=req.approach, skip_homing=req.skip_homing,
                             log_root=req.log_root, cache_dir=req.cache_dir,
                             on_sample=req.on_sample, on_connected=req.on_connected,
                             handle_signals=req.handle_signals, sim_time=True, preview=True)


def _preview(twin: Profile, start: F | None, execution: ExecutionResult,
             homing: ExecutionResult | None, goal_deg: F | None, req: RunRequest,
             run: OneShotResult, t0: float) -> Preview:
    final = None if execution.final_deg is None else np.asarray(execution.final_deg, float)
    data = None if execution.log_dir is None else load_run(execution.log_dir)
    margin, link = (math.nan, math.nan) if data is None else _margins(twin, req, data)
    simulated = execution.stats.duration_s + (0.0 if homing is None else homing.stats.duration_s)
    error = None if final is None or goal_deg is None else final - goal_deg
    runs = [data] + ([] if homing is None or homing.log_dir is None
                     else [load_run(homing.log_dir)])
    track = None if data is None else PredictedTrack(data.columns["t"], data.vec("ref"),
                                                     data.vec("meas"))
    return Preview(run, start, twin.plant.model, error, margin, link,
                   2.0 * twin.links.delta_mm, simulated, time.perf_counter() - t0,
                   _peak_current(runs), track)


def _peak_current(runs: list[RunData | None]) -> F | None:
    """The largest winding current per motor the twin told over these runs' logs (events
    ``peak_current``), A; None when none told one."""
    told = [e.get("peak_current_a") for r in runs if r is not None
            for e in r.events if e.get("event") == "peak_current"]
    peaks = [np.asarray(p, float) for p in told if isinstance(p, list) and len(p) == 3]
    return np.max(peaks, axis=0) if peaks else None


def preview_execute(twin: Profile, plan: Plan, req: RunRequest, source: str | None = None,
                    start_deg: F | None = None) -> Preview:
    """Run ``execute`` of ``plan`` on ``twin`` (the profile with its twin's ``[plant]``) in
    simulated time, from where the wrist rests (``start_deg``, else read as ``req``, the real
    run's request, says)."""
    t0 = time.perf_counter()
    start, sim_req = _twin_request(twin, req, start_deg)
    out = execute_once(twin, plan, sim_req, source=source)
    return replace(_preview(twin, start, out.execution,
                            None if out.homing is None else out.homing.execution,
                            plan.reference_deg[-1], req, out, t0), plan=plan)


def preview_in_session(session: Session, source: str | None = None) -> Preview:
    """The console's preview of executing the session's plan: on the session's twin (its
    profile, whose ``[plant]`` the console chose), powered on where the session reads the
    wrist now (through its own connection: the bus has one owner), the homing the session
    made taken as done. Runs in the caller's thread; the session's bus is not touched
    beyond that one read."""
    plan = session.plans.require("preview")
    if not session.homed:
        raise BadInputError("the wrist is not homed: the preview starts where a homed wrist "
                            "rests")
    here = np.asarray(session.read_position(), float)
    req = RunRequest(faults=session.faults, log_root=session.logs_root,
                     cache_dir=session.cache_dir, handle_signals=False,
                     skip_homing="the console homed the wrist")
    return preview_execute(session.profile, plan, req, source=source, start_deg=here)


def preview_follow(twin: Profile, timed: TimedTargets, req: RunRequest,
                   source: str | None = None) -> Preview | FollowOneShot:
    """Run ``follow`` of the timed targets on ``twin`` in simulated time, from where the wrist
    rests: the preview, or (homing stopped) the homing's result. The final error is against
    the last target."""
    t0 = time.perf_counter()
    start, sim_req = _twin_request(twin, req)
    out = follow_once(twin, sim_req, timed, source=source)
    if out.follow is None:
        return out
    homing = None if out.homing is None else out.homing.execution
    return _preview(twin, start, out.follow.execution, homing, timed.theta_deg[-1], req,
                    OneShotResult(out.follow.execution, out.homing), t0)


def _margins(profile: Profile, req: RunRequest, run: RunData) -> tuple[float, float]:
    """(closest approach to P′'s edge, deg; closest links, mm) over the plan's samples of
    the logged run (NaN, NaN without any)."""
    keep = np.array([p in PLAN_PHASES for p in run.phase], bool)
    theta = run.vec("meas")[keep]
    theta = theta[np.isfinite(theta).all(axis=1)]
    if not len(theta):
        return math.nan, math.nan
    ws, _ = load_or_build(profile, cache_dir=req.cache_dir)
    margin = float(np.min(certified_margin_deg(ws.certified_set(), theta)))
    model, links = model_of(profile), link_model_of(profile)
    rad = np.radians(theta)
    R = platform_rotations(model, rad)  # the unique FK of every sample, as the run's MCAP has it
    if np.isnan(R).any():
        return margin, math.nan
    d, _ = links.min_distance(model.u, model.geom.w(rad), platform_axes(R, model.v_home))
    return margin, float(np.min(d))
