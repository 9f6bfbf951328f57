"""Homing: read the pose, check the assembly mode, move home at bounded speed, seed FK.

1. Read the measured motor angles θ0.
2. Unique FK by continuation from home to θ0 (``SpmModel.track``) must succeed:
   the straight path between home and θ0 then crosses no singularity, so a wrist
   in the home assembly mode stays in it. Otherwise refuse with the
   reason (:class:`~spm_console.errors.UnreachableError`): nothing moves.
3. Move home along that straight line in θ, the farthest joint at
   ``safety.home_speed_degps`` (:func:`~spm_console.motion.plans.line_plan`),
   executed by the :class:`~spm_console.motion.executor.Executor` with all its
   safety checks.
4. Seed FK tracking: the pose at the measured end, tracked from home.

The same straight-line move (``approach``) takes the wrist to a plan's start.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.model import Pose
from spm_console.core.plan import Plan
from spm_console.errors import UnreachableError
from spm_console.formatting import fmt_deg
from spm_console.motion.executor import Executor
from spm_console.motion.plans import line_plan, plan_summary
from spm_console.motion.segments import ExecutionResult, Segment

F = NDArray[np.float64]


@dataclass(frozen=True)
class HomingResult:
    """Outcome of a homing run."""

    execution: ExecutionResult
    start_deg: F
    """Measured θ before the move, deg."""
    start_pose: Pose
    """Unique FK at the start (home assembly mode)."""
    pose: Pose | None
    """Unique FK at the measured end: the seed for live FK tracking (None if stopped early
    without a valid end position)."""


def check_assembly_mode(profile: Profile, theta_deg: F, what: str = "measured position") -> Pose:
    """Unique FK of θ (deg) tracked from home; UnreachableError when it cannot be reached."""
    theta = np.asarray(theta_deg, float)
    r = model_of(profile).track(np.radians(theta))
    if not r.ok or r.pose is None:
        raise UnreachableError(
            f"{what} θ = {fmt_deg(theta)} is not reachable from home in the known "
            f"assembly mode: {r.reason}. Nothing moved; bring the wrist near home by hand "
            "(torque off) and home again"
        )
    return r.pose


def approach_segment(profile: Profile, theta0_deg: F, target_deg: F) -> Segment:
    """Straight-line move at the homing speed from θ0 to a plan's start (both FK-checked)."""
    check_assembly_mode(profile, theta0_deg)
    check_assembly_mode(profile, target_deg, "plan start")
    return Segment("approach", line_plan(profile, theta0_deg, target_deg,
                                         profile.safety.home_speed_degps))


def plan_segments(profile: Profile, theta0_deg: F, plan: Plan, tolerance_deg: float) -> list[Segment]:
    """The plan, preceded by an approach move when the wrist (θ0, deg) is farther than
    ``tolerance_deg`` from its start."""
    start = plan.reference_deg[0]
    segments = [Segment("plan", plan)]
    if float(np.abs(np.asarray(theta0_deg) - start).max()) > tolerance_deg:
        segments.insert(0, approach_segment(profile, theta0_deg, start))
    return segments


def home(executor: Executor) -> HomingResult:
    """Home the wrist through ``executor`` (its bus, log and callbacks)."""
    profile = executor.profile
    theta0 = executor.read_initial()
    start_pose = check_assembly_mode(profile, theta0)
    target = np.asarray(profile.home.theta_deg, float)
    plan = line_plan(profile, theta0, target, profile.safety.home_speed_degps)
    if executor.log is not None:
        executor.log.meta["plans"] = [plan_summary(plan) | {"phase": "homing"}]
    result = executor.run([Segment("homing", plan)], theta0_deg=theta0)
    pose = None
    if result.final_deg is not None:
        r = model_of(profile).track(np.radians(result.final_deg))
        pose = r.pose if r.ok else None
    return HomingResult(execution=result, start_deg=theta0, start_pose=start_pose, pose=pose)
