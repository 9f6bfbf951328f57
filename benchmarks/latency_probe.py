"""The machine's own wake-up latency for a real-time thread, measured beside a benchmark.

A loop's lateness has two parts: what our processes add (GIL, bus, work) and what the
kernel and the host give any real-time thread (a CPU held in a non-preemptible system
call, a virtual CPU descheduled by the host). :func:`wakeup_probe` runs, for the duration
of a block, one process pinned to each CPU that does nothing but sleep a servo period under SCHED_FIFO
just below the servo loop's priority (so it never delays the loop) and record how late each
wake-up came, like ``cyclictest`` (``spm_console.system.host_latency``). Its worst case is the
same run's baseline for the loop's worst lateness: the loop cannot be expected to do better
than an idle thread of (almost) its priority. Also reported: the kernel's preemption model and the CPU time the
host took from this virtual machine (steal) meanwhile.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from dataclasses import dataclass

from spm_console.system.host_latency import measured_meanwhile
from spm_console.system.realtime import LOOP_PRIORITY, kernel_preemption

#: The probe's SCHED_FIFO priority: above everything but the loop and the emulated servos.
PROBE_PRIORITY = LOOP_PRIORITY - 1
#: The probes' sleep, s: the servo period of the shipped profiles, so that they wake no more
#: often than the loop they are compared with (on a virtual machine every timer wake-up costs
#: the host's attention; 1-2 ms probes made the emulated-bus tests fail more often).
PROBE_PERIOD_S = 0.02


@dataclass
class ProbeResult:
    """What the probes saw, over every CPU (filled in when the block ends)."""

    policy: str = "not run"
    wakeups: int = 0
    max_ms: float = float("nan")
    p99_ms: float = float("nan")
    over_2ms: int = 0
    steal_ms: float = float("nan")
    preemption: str = ""

    def summary(self) -> str:
        return (f"an idle SCHED_FIFO-{PROBE_PRIORITY} thread pinned to each CPU, in its own "
                f"process ({self.policy}), {self.wakeups} wake-ups at {PROBE_PERIOD_S * 1e3:.0f} ms: late by max "
                f"{self.max_ms:.2f} ms, p99 {self.p99_ms:.3f} ms (worst CPU), {self.over_2ms} "
                f"≥ 2 ms; host steal {self.steal_ms:.0f} ms; kernel preemption: {self.preemption}")


@contextlib.contextmanager
def wakeup_probe() -> Iterator[ProbeResult]:
    """Measure real-time wake-up latency on every CPU while the block runs
    (``spm_console.system.host_latency``, as ``spm-console latency`` does)."""
    out = ProbeResult(preemption=kernel_preemption())
    with measured_meanwhile(period_s=PROBE_PERIOD_S, priority=PROBE_PRIORITY) as cpus:
        yield out
    if not cpus:
        out.policy = "probe failed"
        return
    out.policy = "; ".join(sorted({c.scheduling for c in cpus}))
    out.wakeups = sum(c.wakeups for c in cpus)
    out.max_ms = max(c.max_ms for c in cpus)
    out.p99_ms = max(c.p99_ms for c in cpus)
    out.over_2ms = sum(dict(c.late)[2.0] for c in cpus)
    steal = [c.steal_ms for c in cpus]
    out.steal_ms = math.fsum(steal) if all(math.isfinite(x) for x in steal) else float("nan")
