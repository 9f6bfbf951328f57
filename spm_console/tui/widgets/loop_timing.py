"""The servo loop's timing as the Execute step shows it: live, sample by sample, and over a
finished run (the motion process's own figures)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from spm_console.motion.sample import Sample

if TYPE_CHECKING:
    from spm_console.motion.stats import RunStats


@dataclass(frozen=True)
class LoopTiming:
    """The servo loop's timing over the cycles seen so far (or over the whole run)."""

    cycles: int
    jitter_p99_ms: float
    """99th percentile of |t(k) − t(k−1) − Ts| over consecutive cycles, ms (NaN: < 2)."""
    late_cycles: int
    """Cycles that started more than one period after their deadline (RunStats.overruns)."""
    read_retries: int
    no_reply: int
    """Cycles without a valid reply after their retries."""
    stale_replies: int
    """Stale status packets the bus discarded (late or unasked-for replies)."""

    def text(self) -> str:
        jit = f"{self.jitter_p99_ms:.2f} ms" if math.isfinite(self.jitter_p99_ms) else "–"
        return (f"servo loop, {self.cycles} cycles: jitter p99 {jit} · "
                f"late cycles {self.late_cycles} · read retries {self.read_retries} · "
                f"no-reply cycles {self.no_reply} · stale replies {self.stale_replies}")

    @classmethod
    def of_run(cls, stats: RunStats) -> LoopTiming:
        """The motion process's own figures over every cycle of a finished run."""
        return cls(cycles=stats.samples,
                   jitter_p99_ms=stats.jitter_ms.p99 if stats.jitter_ms else math.nan,
                   late_cycles=stats.overruns, read_retries=stats.read_retries,
                   no_reply=stats.failed_reads, stale_replies=stats.stale_replies)


class LiveTiming:
    """Loop timing accumulated sample by sample while the wrist moves (the definitions of
    ``run.stats.run_stats``; a cycle the telemetry left out breaks the jitter pair)."""

    def __init__(self, ts_s: float) -> None:
        self.ts_s = ts_s
        """Servo period, s."""
        self._jitter_ms: list[float] = []
        self._prev_k = -2
        self._prev_t = 0.0
        self.cycles = 0
        self.late_cycles = 0
        self.read_retries = 0
        self.no_reply = 0
        self.stale_replies = 0

    def add(self, samples: Sequence[Sample]) -> None:
        for s in samples:
            if s.k == self._prev_k + 1:
                self._jitter_ms.append(abs(s.t - self._prev_t - self.ts_s) * 1e3)
            self._prev_k, self._prev_t = s.k, s.t
            self.cycles += 1
            self.late_cycles += int(s.late_s > self.ts_s)
            self.read_retries += s.retries
            self.no_reply += int(not s.read_ok)
            self.stale_replies = max(self.stale_replies, s.stale_replies)

    def timing(self) -> LoopTiming:
        jit = float(np.percentile(self._jitter_ms, 99)) if self._jitter_ms else math.nan
        return LoopTiming(cycles=self.cycles, jitter_p99_ms=jit, late_cycles=self.late_cycles,
                          read_retries=self.read_retries, no_reply=self.no_reply,
                          stale_replies=self.stale_replies)
