"""What the executor runs (segments of plans) and what it returns (ExecutionResult)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.core.plan import Plan
from spm_console.errors import BadInputError, ExitCode
from spm_console.run.safety import StopReason

F = NDArray[np.float64]

#: A reference on a servo limit up to this much (deg) is on it (floating-point boundary).
LIMIT_TOL_DEG = 1e-9


@dataclass(frozen=True)
class Segment:
    """One part of a run: a phase name and the plan streamed in it."""

    phase: str
    plan: Plan


@dataclass
class ExecutionResult:
    """What a run did (STYLE §8: an object, not a tuple)."""

    outcome: Literal["completed", "stopped"]
    exit_code: ExitCode
    message: str
    log_dir: Path | None
    stop: StopReason | None = None
    final_deg: F | None = None
    """Last measured position, deg."""
    stats: dict[str, Any] = field(default_factory=dict)
    """Sample count, jitter, bus time, retries, tracking RMS …"""

    @property
    def ok(self) -> bool:
        return self.outcome == "completed"


def check_segments(segments: Sequence[Segment], ts: float, lo: F, hi: F) -> None:
    """Refuse segments sampled at another Ts or with references outside [lo, hi] (deg).

    A reference beyond a limit by at most LIMIT_TOL_DEG is on it: the plan's references are
    replaced by a copy with those put exactly on the limit, since the bus refuses any goal
    past a limit (a plan accepted here must not stop on a limit mid-run)."""
    if not segments:
        raise BadInputError("nothing to execute: no plan segments")
    for seg in segments:
        plan = seg.plan
        if abs(plan.Ts - ts) > 1e-9:
            raise BadInputError(
                f"{seg.phase}: plan sampled at Ts = {plan.Ts} s but the profile's servo "
                f"runs at Ts = {ts} s; re-plan with this profile"
            )
        ref = plan.reference_deg
        if ref.ndim != 2 or ref.shape[1] != 3 or not np.all(np.isfinite(ref)):
            raise BadInputError(f"{seg.phase}: references must be finite (N+1, 3) angles")
        bad = (ref < lo - LIMIT_TOL_DEG) | (ref > hi + LIMIT_TOL_DEG)
        if bad.any():
            k, i = (int(x) for x in np.argwhere(bad)[0])
            raise BadInputError(
                f"{seg.phase}: reference θ{i + 1}({k}) = {ref[k, i]:.6f}° is outside the "
                f"servo limits [{lo[i]:.1f}, {hi[i]:.1f}]°; nothing was moved"
            )
        if np.any(ref < lo) or np.any(ref > hi):
            object.__setattr__(plan, "reference_deg", np.clip(ref, lo, hi))
