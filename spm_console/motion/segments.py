"""What the executor runs (segments of plans) and what it returns (ExecutionResult)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.core.plan import Plan
from spm_console.errors import ExitCode
from spm_console.motion.safety import StopReason
from spm_console.motion.stats import RunStats, SettleOutcome

F = NDArray[np.float64]

@dataclass(frozen=True)
class Segment:
    """One part of a run: a phase name and the plan streamed in it."""

    phase: str
    plan: Plan


@dataclass
class ExecutionResult:
    """What a run did (an object, not a tuple)."""

    outcome: Literal["completed", "stopped"]
    exit_code: ExitCode
    message: str
    log_dir: Path | None
    stop: StopReason | None = None
    final_deg: F | None = None
    """Last measured position, deg."""
    stats: RunStats = field(default_factory=RunStats)
    """Sample count, jitter, bus time, retries, tracking RMS, stop timing."""
    realtime: str = ""
    """The scheduling the servo loop got, e.g. "SCHED_FIFO priority 40" ("" when no loop ran)."""
    realtime_granted: bool = False
    """SCHED_FIFO was granted (else the loop ran at a raised or normal priority)."""
    settle: SettleOutcome | None = None
    """How the settling at the plan's goal ended (None: the run did not settle)."""

    @property
    def ok(self) -> bool:
        return self.outcome == "completed"
