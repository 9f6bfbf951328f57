"""Homing and execution on an open bus: the one orchestration every front end reaches
(through the motion process for the console and scripts, directly for the CLI).

Each run creates its log, builds the executor (which verifies every segment against this
profile's workspace before torque-on) and hands it to ``attach`` so that an E-stop reaches
it from then on. Degrees, seconds.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from spm_console.core.plan import Plan
from spm_console.core.workspace import Workspace
from spm_console.devices.base import ServoBus
from spm_console.profile import Profile
from spm_console.run.executor import Executor
from spm_console.run.homing import HomingResult, check_assembly_mode, home, plan_segments
from spm_console.run.plans import plan_summary
from spm_console.run.runlog import RunLog
from spm_console.run.sample import Sample
from spm_console.run.segments import ExecutionResult

SampleCallback = Callable[[Sample], None]
Attach = Callable[[Executor], None]


@dataclass(frozen=True)
class RunContext:
    """Where a run happens: the one run-log metadata schema of every front end."""

    port: str
    """The serial port (the emulator's pty for the emulated bus)."""
    sim: bool
    """Emulated bus."""
    faults: tuple[str, ...] = ()
    """Faults injected into the emulated bus."""
    logs_root: str | None = None

    @property
    def bus_label(self) -> str:
        return "emulated bus" if self.sim else f"serial port {self.port}"

    def meta(self) -> dict[str, Any]:
        return {"bus": self.bus_label, "port": self.port, "sim": self.sim,
                "faults": list(self.faults)}


def _executor(profile: Profile, bus: ServoBus, ws: Workspace, kind: str,
              plans: list[dict[str, Any]], ctx: RunContext,
              on_sample: SampleCallback | None) -> Executor:
    log = RunLog.create(kind, profile.name, profile.digest(), plans, root=ctx.logs_root,
                        extra=ctx.meta())
    return Executor(profile, bus, workspace=ws, log=log, on_sample=on_sample)


def run_home(profile: Profile, bus: ServoBus, ws: Workspace, ctx: RunContext,
             on_sample: SampleCallback | None, attach: Attach) -> HomingResult:
    """Home the wrist (assembly-mode check first: a refusal makes no log folder)."""
    from spm_console.devices.base import read_position_settled

    check_assembly_mode(profile, read_position_settled(bus, 3))
    ex = _executor(profile, bus, ws, "home", [{"kind": "homing"}], ctx, on_sample)
    attach(ex)
    return home(ex)


def run_execute(profile: Profile, bus: ServoBus, ws: Workspace, plan: Plan, ctx: RunContext,
                on_sample: SampleCallback | None, attach: Attach,
                approach_tolerance_deg: float | None = None) -> ExecutionResult:
    """Execute ``plan``, with a straight approach move to its start when the wrist is farther
    than the tolerance (default: the profile's ``safety.approach_tolerance_deg``)."""
    from spm_console.devices.base import read_position_settled

    theta0 = np.asarray(read_position_settled(bus, 3), float)
    ex = _executor(profile, bus, ws, "execute", [plan_summary(plan)], ctx, on_sample)
    tol = profile.safety.approach_tolerance_deg if approach_tolerance_deg is None else approach_tolerance_deg
    segments = plan_segments(profile, theta0, plan, tol)
    if ex.log is not None:
        ex.log.meta["plans"] = [plan_summary(s.plan) | {"phase": s.phase} for s in segments]
    attach(ex)
    return ex.run(segments, theta0_deg=theta0)
