"""A script's values under the same input rules as the command line, before anything runs.

The TOML schema (:mod:`spm_console.scripting.steps`) fixes types and fixed bounds; what
depends on the profile — servo limits, the workspace grid, the planning speed limit, the
orientations IK places, the rules of timed targets — is checked here with the rules the CLI
applies to its options (:mod:`spm_console.input_rules`) and to its target files
(:mod:`spm_console.store.target_file`). A refusal names the script file, the step and the key
(and a target's row, or a target file's line), before the bus is opened.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from spm_console.config.schema import Profile
from spm_console.core.workspace.build import check_theta
from spm_console.core.workspace.data import Workspace
from spm_console.devices.emulator.faults import parse_fault
from spm_console.errors import BadInputError, InfeasibleError, Issue, SpmError
from spm_console.formatting import fmt_deg
from spm_console.input_rules import theta_for_fk, theta_in_grid, theta_in_servo_limits, vmax_arg
from spm_console.scripting.steps import (
    AssertStep,
    ExecuteStep,
    FkStep,
    FollowStep,
    PlanStep,
    PoseIn,
    RpyPose,
    Script,
    ThetaPose,
    WaitStep,
    WorkspaceStep,
)
from spm_console.store.target_file import read_target_csv, theta_of_rpy, timed_targets


def _endpoint(theta: list[float], what: str, profile: Profile) -> None:
    """As ``plan --start/--goal``: inside the servo limits and the grid."""
    theta_in_servo_limits(theta, what, profile)
    theta_in_grid(theta, what, profile)


def _pose(pose: PoseIn, where: str, key: str, profile: Profile) -> tuple[list[float], str] | None:
    """(θ, how the refusal names it) of an end given as θ or as an orientation, checked
    as ``plan --start/--goal``; None for "current" and "home"."""
    if isinstance(pose, ThetaPose):
        theta, what = list(pose.theta), f"{where} '{key}.theta'"
    elif isinstance(pose, RpyPose):  # the θ the plan will start or end at, found as the step will
        what = f"{where} '{key}.rpy'"
        theta = [float(x) for x in theta_of_rpy(profile, pose.rpy, what)]
    else:
        return None
    _endpoint(theta, what, profile)
    return theta, what


def _follow(step: FollowStep, where: str, profile: Profile) -> None:
    if step.targets is not None:  # the rows as the step will take them
        timed_targets(profile, [(f"{where} 'targets' row {k}", r)
                                for k, r in enumerate(step.targets, 1)], step.rpy)
    elif step.file is not None:  # read and checked now (as the step will read it)
        try:
            read_target_csv(profile, Path(step.file), step.rpy)
        except SpmError as exc:
            raise exc.at(f"{where} 'file'") from None


#: Longest time a script's ``wait`` steps may add up to, s (each is at most an hour).
MAX_SCRIPT_WAIT_S = 24 * 3600.0
_CONDITIONS = ("outcome", "exit_code", "theta_near", "feasible", "zeta_min", "max_duration_s")


def _order(script: Script) -> None:
    """What the steps' order alone decides: an ``execute`` (or an ``assert`` of a plan's
    duration) needs a ``plan`` step before it, an ``assert`` a condition; the waits add up
    to at most :data:`MAX_SCRIPT_WAIT_S`."""
    planned = False
    waits = 0.0
    for i, step in enumerate(script.step, 1):
        if isinstance(step, PlanStep):
            planned = True
        elif isinstance(step, ExecuteStep) and not planned:
            raise BadInputError(f"step {i} (execute): no plan step before it: nothing to execute")
        elif isinstance(step, AssertStep):
            if all(getattr(step, c) is None for c in _CONDITIONS):
                raise BadInputError(f"step {i} (assert): no condition given (one or more of "
                                    f"{', '.join(_CONDITIONS)})")
            if step.max_duration_s is not None and not planned:
                raise BadInputError(f"step {i} (assert) key 'max_duration_s': no plan step "
                                    "before it")
        elif isinstance(step, WaitStep):
            waits += float(step.seconds)
    if waits > MAX_SCRIPT_WAIT_S:
        raise BadInputError(f"the wait steps add up to {waits:.0f} s; a script waits at most "
                            f"{MAX_SCRIPT_WAIT_S:.0f} s (24 h) in all")


def _check(script: Script, profile: Profile) -> None:
    _order(script)
    for k, text in enumerate(script.session.faults, 1):  # as the session will parse them
        try:
            parse_fault(text)
        except SpmError as exc:
            raise exc.at(f"[session] key 'faults' item {k} ({text!r})") from None
    if script.session.initial_deg is not None:
        theta_in_servo_limits(list(script.session.initial_deg), "[session] key 'initial_deg'",
                              profile)
    for i, step in enumerate(script.step, 1):
        where = f"step {i} ({step.do}) key"
        if isinstance(step, FkStep):
            if (step.theta is None) == (step.rpy is None):
                raise BadInputError(f"step {i} (fk): give exactly one of theta or rpy")
            if step.theta is not None:
                theta_for_fk(list(step.theta), f"{where} 'theta'")
            if step.rpy is not None:  # as the step will take it: within ±360°, IK places it
                theta_of_rpy(profile, step.rpy, f"{where} 'rpy'")
        elif isinstance(step, WorkspaceStep) and step.check is not None:
            theta_in_grid(list(step.check), f"{where} 'check'", profile)
        elif isinstance(step, PlanStep):
            vmax_arg(step.vmax, profile, what=f"{where} 'vmax' =")
            _pose(step.start, where, "start", profile)
            _pose(step.goal, where, "goal", profile)
        elif isinstance(step, FollowStep):
            if (step.targets is None) == (step.file is None):
                raise BadInputError(f"step {i} (follow): give exactly one of targets or file")
            _follow(step, where, profile)
        elif isinstance(step, AssertStep) and step.theta_near is not None:
            theta_for_fk(list(step.theta_near), f"{where} 'theta_near'")


def plan_ends(script: Script, profile: Profile) -> list[tuple[list[float], str]]:
    """The plan steps' starts and goals given as θ or orientations: (θ in degrees, how a
    refusal names it), in step order (:func:`check_script` has checked them)."""
    out = []
    for i, step in enumerate(script.step, 1):
        if isinstance(step, PlanStep):
            for key in ("start", "goal"):
                end = _pose(getattr(step, key), f"step {i} (plan) key", key, profile)
                if end is not None:
                    out.append(end)
    return out


def check_plan_ends(script: Script, profile: Profile, workspace: Workspace) -> None:
    """Every plan step's start and goal given as θ or an orientation is feasible in
    ``workspace`` (as the plan step will check them): else InfeasibleError (exit 6) naming
    the script's file, the step and the key, before the bus is opened."""
    for theta, what in plan_ends(script, profile):
        chk = check_theta(workspace, np.asarray(theta, float))
        if not chk.feasible:
            raise InfeasibleError(f"{what}: θ = {fmt_deg(theta)} is {chk.verdict}",
                                  Issue.END_NOT_FEASIBLE).at(script.source)


def check_script(script: Script, profile: Profile) -> None:
    """Every profile-dependent input rule of ``script``, and what the steps' order decides
    (:func:`_order`): a refusal (BadInputError, exit 4;
    UnreachableError, exit 5, for an orientation IK cannot place) names the script's file,
    the step and the key."""
    try:
        _check(script, profile)
    except SpmError as exc:
        raise exc.at(script.source) from None
