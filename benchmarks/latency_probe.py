"""The machine's own wake-up latency for a real-time thread, measured beside a benchmark.

A loop's lateness has two parts: what our processes add (GIL, bus, work) and what the
kernel and the host give any real-time thread (a CPU held in a non-preemptible system
call, a virtual CPU descheduled by the host). :func:`wakeup_probe` runs, for the duration
of a block, a separate process that does nothing but sleep 1 ms under SCHED_FIFO just
below the servo loop's priority (so it never delays the loop) and record how late each
wake-up came, like ``cyclictest``. Its worst case is the same run's baseline for the
loop's worst lateness: the loop cannot be expected to do better than an idle thread of
(almost) its priority. Also reported: the kernel's preemption model and the CPU time the
host took from this virtual machine (steal) meanwhile.
"""

from __future__ import annotations

import contextlib
import json
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass

from spm_console.realtime import LOOP_PRIORITY, kernel_preemption

#: The probe's SCHED_FIFO priority: above everything but the loop and the emulated servos.
PROBE_PRIORITY = LOOP_PRIORITY - 1

_PROBE = r"""
import json, os, sys, time, select
try:
    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(int(sys.argv[1])))
    policy = "SCHED_FIFO"
except OSError:
    policy = "normal"
def steal():
    with open("/proc/stat") as f:
        return int(f.readline().split()[8])
s0 = steal()
lat = []
nxt = time.monotonic()
while not select.select([sys.stdin], [], [], 0)[0]:
    nxt += 0.001
    d = nxt - time.monotonic()
    if d > 0:
        time.sleep(d)
    late = time.monotonic() - nxt
    lat.append(late)
    if late > 0.001:
        nxt = time.monotonic()
lat.sort()
n = len(lat)
print(json.dumps({"policy": policy, "n": n, "max_ms": 1e3 * lat[-1] if n else float("nan"),
                  "p99_ms": 1e3 * lat[int(0.99 * (n - 1))] if n else float("nan"),
                  "over_2ms": sum(1 for x in lat if x > 0.002),
                  "steal_ms": 10.0 * (steal() - s0)}))
"""


@dataclass
class ProbeResult:
    """What the probe saw (filled in when the block ends)."""

    policy: str = "not run"
    wakeups: int = 0
    max_ms: float = float("nan")
    p99_ms: float = float("nan")
    over_2ms: int = 0
    steal_ms: float = float("nan")
    preemption: str = ""

    def summary(self) -> str:
        return (f"an idle SCHED_FIFO-{PROBE_PRIORITY} thread in its own process ({self.policy}), "
                f"{self.wakeups} wake-ups at 1 ms: late by max {self.max_ms:.2f} ms, p99 "
                f"{self.p99_ms:.3f} ms, {self.over_2ms} over 2 ms; host steal "
                f"{self.steal_ms:.0f} ms; kernel preemption: {self.preemption}")


@contextlib.contextmanager
def wakeup_probe() -> Iterator[ProbeResult]:
    """Measure real-time wake-up latency while the block runs."""
    out = ProbeResult(preemption=kernel_preemption())
    proc = subprocess.Popen([sys.executable, "-c", _PROBE, str(PROBE_PRIORITY)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        yield out
    finally:
        try:
            text, _ = proc.communicate("stop\n", timeout=30)
            got = json.loads(text)
            out.policy, out.wakeups = got["policy"], got["n"]
            out.max_ms, out.p99_ms = got["max_ms"], got["p99_ms"]
            out.over_2ms, out.steal_ms = got["over_2ms"], got["steal_ms"]
        except (subprocess.TimeoutExpired, ValueError, KeyError):
            proc.kill()
            proc.wait()
            out.policy = "probe failed"
