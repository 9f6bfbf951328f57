"""A script's values under the same input rules as the command line, before anything runs.

The TOML schema (:mod:`spm_console.scripting.steps`) fixes types and fixed bounds; what
depends on the profile — servo limits, the workspace grid, the planning speed limit — is
checked here with :mod:`spm_console.input_rules`, the rules the CLI applies to its options.
A refusal names the step and key (exit 4), before the bus is opened.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from spm_console.config.schema import Profile
from spm_console.core.planning.follow.timed import TimedTargets
from spm_console.errors import BadInputError
from spm_console.input_rules import (
    rpy_angles,
    theta_for_fk,
    theta_in_grid,
    theta_in_servo_limits,
    vmax_arg,
)
from spm_console.scripting.steps import (
    AssertStep,
    FkStep,
    FollowStep,
    PlanStep,
    PoseIn,
    RpyPose,
    Script,
    ThetaPose,
    WorkspaceStep,
)
from spm_console.store.target_file import read_target_csv


def _pose(pose: PoseIn, where: str, key: str, profile: Profile) -> None:
    if isinstance(pose, ThetaPose):  # as `plan --start/--goal`: servo limits and the grid
        theta_in_servo_limits(list(pose.theta), f"{where} '{key}.theta'", profile)
        theta_in_grid(list(pose.theta), f"{where} '{key}.theta'", profile)
    elif isinstance(pose, RpyPose):
        rpy_angles(list(pose.rpy), f"{where} '{key}.rpy'")


def _targets(step: FollowStep, where: str) -> None:
    assert step.targets is not None
    rows = np.asarray(step.targets, float)
    if step.rpy:
        for r in rows[:, 1:]:
            rpy_angles(list(r), f"{where} 'targets'")
    try:  # times (and θ, unless orientations) as the runtime will take them
        TimedTargets(rows[:, 0], np.zeros((len(rows), 3)) if step.rpy else rows[:, 1:])
    except BadInputError as exc:
        raise BadInputError(f"{where} 'targets': {exc.message}") from None


def check_script(script: Script, profile: Profile) -> None:
    """Every profile-dependent input rule of ``script`` (BadInputError naming step and key)."""
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
            if step.rpy is not None:
                rpy_angles(list(step.rpy), f"{where} 'rpy'")
        elif isinstance(step, WorkspaceStep) and step.check is not None:
            theta_in_grid(list(step.check), f"{where} 'check'", profile)
        elif isinstance(step, PlanStep):
            vmax_arg(step.vmax, profile, what=f"{where} 'vmax' =")
            _pose(step.start, where, "start", profile)
            _pose(step.goal, where, "goal", profile)
        elif isinstance(step, FollowStep):
            if (step.targets is None) == (step.file is None):
                raise BadInputError(f"step {i} (follow): give exactly one of targets or file")
            if step.targets is not None:
                _targets(step, where)
            else:  # read and checked now (as the step will read it): nothing moves first
                assert step.file is not None
                read_target_csv(profile, Path(step.file), step.rpy)
        elif isinstance(step, AssertStep) and step.theta_near is not None:
            theta_for_fk(list(step.theta_near), f"{where} 'theta_near'")
