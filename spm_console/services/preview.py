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
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import link_model_of, model_of
from spm_console.config.schema import Profile
from spm_console.core.plan import Plan
from spm_console.core.planning.follow.timed import TimedTargets
from spm_console.core.workspace.margin import certified_margin_deg
from spm_console.motion.logs.runlog import load_run
from spm_console.motion.segments import ExecutionResult
from spm_console.services.oneshot import (
    FollowOneShot,
    OneShotResult,
    RunRequest,
    execute_once,
    follow_once,
    one_shot,
)
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


def rest_pose(profile: Profile, req: RunRequest) -> F | None:
    """Where the wrist rests: read on the real bus (one connection, nothing moves); on the
    emulated bus its power-on pose (``req.sim_start_deg``, None: the profile's home)."""
    if req.emulated(profile):
        return None if req.sim_start_deg is None else np.asarray(req.sim_start_deg, float)
    read = RunRequest(port=req.port, log_root=req.log_root, cache_dir=req.cache_dir,
                      handle_signals=req.handle_signals)
    return np.asarray(one_shot(profile, "preview", read, lambda s: s.read_position()), float)


def _twin_request(twin: Profile, req: RunRequest) -> tuple[F | None, RunRequest]:
    """Where the wrist rests, and the request that runs ``req``'s command on the twin powered
    on there, in simulated time, logged as a preview."""
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
    margin, link = _margins(twin, req, execution.log_dir)
    simulated = execution.stats.duration_s + (0.0 if homing is None else homing.stats.duration_s)
    error = None if final is None or goal_deg is None else final - goal_deg
    return Preview(run, start, twin.plant.model, error, margin, link,
                   2.0 * twin.links.delta_mm, simulated, time.perf_counter() - t0)


def preview_execute(twin: Profile, plan: Plan, req: RunRequest,
                    source: str | None = None) -> Preview:
    """Run ``execute`` of ``plan`` on ``twin`` (the profile with its twin's ``[plant]``) in
    simulated time, from where the wrist rests (``req``: the real run's request)."""
    t0 = time.perf_counter()
    start, sim_req = _twin_request(twin, req)
    out = execute_once(twin, plan, sim_req, source=source)
    return _preview(twin, start, out.execution,
                    None if out.homing is None else out.homing.execution,
                    plan.reference_deg[-1], req, out, t0)


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


def _margins(profile: Profile, req: RunRequest, log_dir: str | Path | None) -> tuple[float, float]:
    """(closest approach to P′'s edge, deg; closest links, mm) over the plan's samples of
    the run logged in ``log_dir`` (NaN, NaN without any)."""
    if log_dir is None:
        return math.nan, math.nan
    run = load_run(log_dir)
    keep = np.array([p in PLAN_PHASES for p in run.phase], bool)
    theta = run.vec("meas")[keep]
    theta = theta[np.isfinite(theta).all(axis=1)]
    if not len(theta):
        return math.nan, math.nan
    ws, _ = load_or_build(profile, cache_dir=req.cache_dir)
    margin = float(np.min(certified_margin_deg(ws.certified_set(), theta)))
    model, links = model_of(profile), link_model_of(profile)
    closest = math.inf
    prev: tuple[F, F] | None = None  # each sample's pose continued from the last one's
    for th in np.radians(theta):
        r = model.track(th) if prev is None else model.track(th, *prev)
        if not (r.ok and r.pose is not None):
            return margin, math.nan
        prev = (th, r.pose.R)
        d, _ = links.min_distance(model.u, model.geom.w(th), r.pose.v)
        closest = min(closest, float(d))
    return margin, closest
