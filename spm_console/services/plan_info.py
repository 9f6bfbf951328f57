"""What the session knows of its current plan beyond the plan itself: how the operator
asked for it (or which file it came from) and whether it ran. Degrees, deg/s."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from spm_console.core.plan import Plan
from spm_console.formatting import fmt_deg

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
