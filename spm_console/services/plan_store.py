"""The session's current plan (a part of the operator session: ``session.plans``): the plan,
how the operator asked for it (or which file it came from) and whether it ran. Plans are
solved or opened here and passed to the bus as arguments. Degrees, deg/s."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.core.plan import Plan
from spm_console.errors import BadInputError, Issue
from spm_console.formatting import fmt_deg
from spm_console.motion.plan_check import verify_plan
from spm_console.services.wrist_service import PoseSpec, WristService
from spm_console.store.plan_file import load_plan

F = NDArray[np.float64]


@dataclass(frozen=True)
class PlanInfo:
    """The current plan's request and state (a new one replaces it: never edited)."""

    method: str
    """The plan's kind ("mvn" or "mintime")."""
    start: str
    """The start as the operator gave it (e.g. "home", "θ = [...]")."""
    goal: str
    """The goal as the operator gave it."""
    start_deg: F
    """Start θ (deg)."""
    goal_deg: F
    """Goal θ (deg)."""
    vmax_degps: float | None
    """The speed bound asked for (None: unknown, a saved plan without options)."""
    region: str
    """One line naming the region(s) the plan lies in."""
    source: str | None = None
    """The file the plan was opened from (None: solved in this session)."""
    start_read: bool = False
    """The start was read from the servos just before solving."""
    executed: bool = False
    """An execution of this plan ran (whatever its outcome)."""
    executed_ok: bool = False
    """The last execution of this plan ended at its goal."""

    @classmethod
    def of_file(cls, plan: Plan, path: str | Path) -> PlanInfo:
        """The info of a plan opened from ``path``: its ends are its first and last θ."""
        start, goal = plan.position_deg[0], plan.position_deg[-1]
        return cls(method=plan.kind, start=f"θ = {fmt_deg(start)}", goal=f"θ = {fmt_deg(goal)}",
                   start_deg=start, goal_deg=goal,
                   vmax_degps=None if plan.options is None else plan.options.vmax_degps,
                   region=plan.summary().stored_region(),
                   source=str(path))


class PlanStore:
    """The current plan of a session on ``wrist`` (its profile and workspace), its info and
    the file it came from (None: none yet)."""

    def __init__(self, wrist: WristService) -> None:
        self.wrist = wrist
        self.plan: Plan | None = None
        self.info: PlanInfo | None = None
        """How the current plan was asked for and whether it ran (None without a plan)."""
        self.source: str | None = None
        """The file the current plan was loaded from (None: solved in this session)."""

    def require(self, doing: str = "execute") -> Plan:
        """The current plan, else BadInputError saying there is none to ``doing``."""
        if self.plan is None:
            raise BadInputError(f"no plan to {doing}: solve one first", Issue.NO_PLAN)
        return self.plan

    def clear(self) -> None:
        """No current plan (a refused or failed solve took the place of the one shown)."""
        self.plan, self.info, self.source = None, None, None

    def solve(
        self,
        method: Literal["mvn", "mintime"],
        start: PoseSpec,
        goal: PoseSpec,
        current_deg: F | None = None,
        steps: int = 150,
        vmax_degps: float | None = None,
        intersample: int = 1,
        hold_first: bool = True,
        start_read: bool = False,
    ) -> Plan:
        """MVN (30) in ``steps`` intervals or minimum time (31) under ``vmax_degps`` (default
        the profile's limit), in P or a region grown around the segment, inside the servo
        limits (:func:`~spm_console.services.plan_request.plan_motion`); ``current_deg``:
        the measured θ a 'current' start or goal stands for; ``start_read``: it was read from
        the servos just before solving (said in :class:`PlanInfo`). Kept as the current plan."""
        from spm_console.services.plan_request import PlanRequest, plan_motion

        wrist = self.wrist
        ws = wrist.ensure_workspace()
        s, g = wrist.resolve(start, current_deg), wrist.resolve(goal, current_deg)
        vmax = wrist.profile.limits.vmax_degps if vmax_degps is None else vmax_degps
        planned = plan_motion(wrist.profile, ws, PlanRequest(
            method, s, g, int(steps), vmax, intersample=int(intersample), hold_first=hold_first))
        self.plan = planned.plan
        self.source = None
        self.info = PlanInfo(method=method, start=start.describe(), goal=goal.describe(),
                             start_deg=s, goal_deg=g, vmax_degps=vmax,
                             region=planned.describe_region(), start_read=start_read)
        return self.plan

    def open(self, path: str | Path) -> Plan:
        """A saved plan as the current plan: read and checked against the wrist's profile
        (``store.plan_file.load_plan``: format, profile hash, model), then verified exactly as
        the executor will (``motion.plan_check.verify_plan``). Refused with the reason."""
        plan = load_plan(path, self.wrist.profile)
        verify_plan(self.wrist.profile, self.wrist.ensure_workspace(), plan)
        self.plan = plan
        self.info = PlanInfo.of_file(plan, path)
        self.source = str(path)
        return plan

    def ran(self, plan: Plan, ok: bool) -> None:
        """An execution of ``plan`` ended (``ok``: at its goal); noted when it is the current plan."""
        if plan is self.plan and self.info is not None:
            self.info = replace(self.info, executed=True, executed_ok=ok)
