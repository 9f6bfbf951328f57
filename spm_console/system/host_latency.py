"""How late this machine wakes a real-time thread, per CPU: is it fit to run the servo loop?

The servo loop sleeps until the next period, sends, and waits at most the bus's reply
timeout for the answer. A machine that does not run a thread when it is due (a virtual CPU
the hypervisor did not schedule, a kernel section that cannot be preempted, firmware) turns
that lateness into late cycles, failed reads and, when it lasts several periods,
"communication lost". No software setting removes it; it can be measured, as ``cyclictest``
does for PREEMPT_RT kernels: one thread per CPU, pinned, at the servo loop's SCHED_FIFO
priority, sleeps ``period`` at a time and records by how much each wake-up came late.

``python -m spm_console.system.host_latency --cpu N --seconds S`` measures one CPU and prints one
JSON object (:class:`CpuLatency`); ``--stream`` instead prints one line per wake-up at least
``--report-ms`` late (``<CLOCK_MONOTONIC s> <late ms>``) until its parent ends (the test
suite's stall probes). :func:`measure` runs one such process per allowed CPU at once (one
process each: threads of one interpreter would wait for each other's GIL) for a given time;
:func:`measured_meanwhile` while a block runs (the benchmarks' baseline for the loop's own
lateness). Each result also carries the CPU time the hypervisor took from that CPU (steal).
Times: seconds, except fields named ``_ms``.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import select
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from spm_console.errors import SpmError
from spm_console.system.realtime import LOOP_PRIORITY, request_realtime

#: Lateness thresholds reported as counts, ms.
THRESHOLDS_MS = (1.0, 2.0, 4.0, 10.0, 20.0, 50.0)
#: Longest measurement, s.
MAX_SECONDS = 600.0
DEFAULT_PERIOD_S = 0.001


class HostLatencyError(SpmError):
    """A measuring process failed or did not answer."""


@dataclass(frozen=True)
class CpuLatency:
    """Wake-up lateness of a real-time thread pinned to one CPU."""

    cpu: int
    scheduling: str
    """What the thread got, e.g. "SCHED_FIFO priority 40" (see :mod:`spm_console.system.realtime`)."""
    seconds: float
    period_ms: float
    wakeups: int
    p50_ms: float
    p99_ms: float
    max_ms: float
    late: tuple[tuple[float, int], ...]
    """(threshold ms, wake-ups at least that late), thresholds ascending (by default
    :data:`THRESHOLDS_MS`)."""
    steal_ms: float = float("nan")
    """CPU time the hypervisor took from this CPU meanwhile (``/proc/stat`` steal), ms;
    NaN where the kernel does not say."""

    def per_minute(self, threshold_ms: float) -> float:
        """Wake-ups at least ``threshold_ms`` late per minute (thresholds of :attr:`late`)."""
        n = dict(self.late)[threshold_ms]
        return n * 60.0 / self.seconds if self.seconds > 0 else 0.0


def summarize(cpu: int, scheduling: str, seconds: float, period_s: float, late_ms: np.ndarray,
              thresholds_ms: Sequence[float] = THRESHOLDS_MS,
              steal_ms: float = float("nan")) -> CpuLatency:
    """The statistics of one CPU's wake-up lateness (ms, one value per wake-up)."""
    x = np.asarray(late_ms, float)
    q = (lambda p: float(np.percentile(x, p))) if x.size else (lambda p: float("nan"))
    return CpuLatency(
        cpu=cpu, scheduling=scheduling, seconds=seconds, period_ms=period_s * 1e3,
        wakeups=int(x.size), p50_ms=q(50), p99_ms=q(99),
        max_ms=float(x.max()) if x.size else float("nan"),
        late=tuple((float(t), int((x >= t).sum())) for t in sorted(set(thresholds_ms))),
        steal_ms=steal_ms,
    )


def _pin(cpu: int, priority: int) -> str:
    os.sched_setaffinity(0, {cpu})
    return request_realtime(priority).detail


def _steal_ms(cpu: int) -> float:
    """This CPU's steal time so far, ms (USER_HZ ticks of ``/proc/stat``), NaN if unknown."""
    try:
        with open("/proc/stat", encoding="ascii") as f:
            for line in f:
                if line.startswith(f"cpu{cpu} "):
                    return int(line.split()[8]) * 1e3 / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        pass
    return float("nan")


def _wakeups(period_s: float) -> Iterator[tuple[float, float]]:
    """Sleep ``period_s`` at a time, forever; yield (CLOCK_MONOTONIC s, lateness ms) each wake-up."""
    prev = time.monotonic()
    while True:
        time.sleep(period_s)
        now = time.monotonic()
        yield now, (now - prev - period_s) * 1e3
        prev = now


def _run_one(cpu: int, seconds: float | None, period_s: float, priority: int,
             thresholds_ms: Sequence[float]) -> CpuLatency:
    """Measure for ``seconds``, or (None) until standard input has data or ends."""
    scheduling = _pin(cpu, priority)
    late: list[float] = []
    t_start = now = time.monotonic()
    steal0 = _steal_ms(cpu)
    t_end = t_start + seconds if seconds is not None else float("inf")
    look_every = max(1, round(0.05 / period_s))  # at standard input: about every 50 ms
    for now, late_ms in _wakeups(period_s):
        late.append(max(0.0, late_ms))
        if now >= t_end or (seconds is None and len(late) % look_every == 0
                            and select.select([sys.stdin], [], [], 0)[0]):
            break
    return summarize(cpu, scheduling, now - t_start, period_s, np.array(late), thresholds_ms,
                     _steal_ms(cpu) - steal0)


def _stream(cpu: int, period_s: float, priority: int, report_ms: float) -> None:
    parent = os.getppid()
    print(f"# cpu {cpu}: {_pin(cpu, priority)}", flush=True)
    for n, (now, late_ms) in enumerate(_wakeups(period_s), 1):
        if late_ms >= report_ms:
            print(f"{now:.6f} {late_ms:.3f}", flush=True)
        if n % 256 == 0 and os.getppid() != parent:
            return


def _start(cpus: Sequence[int], period_s: float, priority: int, thresholds_ms: Sequence[float],
           seconds: float | None) -> list[subprocess.Popen[str]]:
    length = ["--seconds", repr(seconds)] if seconds is not None else ["--until-input"]
    return [subprocess.Popen(
        [sys.executable, "-m", "spm_console.system.host_latency", "--cpu", str(c), *length,
         "--period-ms", repr(period_s * 1e3), "--priority", str(priority),
         "--thresholds-ms", ",".join(repr(float(t)) for t in thresholds_ms)],
        stdout=subprocess.PIPE, stdin=subprocess.PIPE if seconds is None else subprocess.DEVNULL,
        text=True) for c in cpus]


def _collect(cpus: Sequence[int], procs: list[subprocess.Popen[str]], timeout_s: float,
             say_stop: bool) -> list[CpuLatency]:
    out: list[CpuLatency] = []
    try:
        for c, p in zip(cpus, procs, strict=True):
            try:
                text, _ = p.communicate("stop\n" if say_stop else None, timeout=timeout_s)
                d = json.loads(text)
                d["late"] = tuple((float(t), int(n)) for t, n in d["late"])
                out.append(CpuLatency(**d))
            except (subprocess.TimeoutExpired, ValueError, TypeError, KeyError, OSError) as exc:
                raise HostLatencyError(f"the measurement on CPU {c} failed "
                                       f"(exit code {p.poll()}): {exc}") from None
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()
    return out


def measure(seconds: float, period_s: float = DEFAULT_PERIOD_S, priority: int = LOOP_PRIORITY,
            cpus: Sequence[int] | None = None,
            thresholds_ms: Sequence[float] = THRESHOLDS_MS) -> list[CpuLatency]:
    """Measure every allowed CPU (or ``cpus``) at once for ``seconds``; one process each."""
    chosen = sorted(os.sched_getaffinity(0)) if cpus is None else list(cpus)
    procs = _start(chosen, period_s, priority, thresholds_ms, seconds)
    return _collect(chosen, procs, seconds + 60.0, say_stop=False)


@contextlib.contextmanager
def measured_meanwhile(period_s: float = DEFAULT_PERIOD_S, priority: int = LOOP_PRIORITY,
                       thresholds_ms: Sequence[float] = THRESHOLDS_MS) -> Iterator[list[CpuLatency]]:
    """Measure every allowed CPU while the block runs; the list is filled when it ends
    (and stays empty when a measurement failed: the block's own outcome is not masked)."""
    chosen = sorted(os.sched_getaffinity(0))
    procs = _start(chosen, period_s, priority, thresholds_ms, None)
    out: list[CpuLatency] = []
    try:
        yield out
    finally:
        with contextlib.suppress(HostLatencyError):
            out.extend(_collect(chosen, procs, 30.0, say_stop=True))


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="wake-up lateness of a real-time thread on one CPU")
    ap.add_argument("--cpu", type=int, required=True)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--until-input", action="store_true",
                    help="measure until standard input has a line or ends (not --seconds)")
    ap.add_argument("--period-ms", type=float, default=DEFAULT_PERIOD_S * 1e3)
    ap.add_argument("--priority", type=int, default=LOOP_PRIORITY)
    ap.add_argument("--stream", action="store_true", help="print late wake-ups until the parent ends")
    ap.add_argument("--report-ms", type=float, default=2.0)
    ap.add_argument("--thresholds-ms", default=",".join(str(t) for t in THRESHOLDS_MS))
    a = ap.parse_args(argv)
    period_s = a.period_ms / 1e3
    if a.stream:
        with contextlib.suppress(BrokenPipeError, KeyboardInterrupt):
            _stream(a.cpu, period_s, a.priority, a.report_ms)
        return 0
    thresholds = [float(t) for t in a.thresholds_ms.split(",") if t.strip()]
    r = _run_one(a.cpu, None if a.until_input else a.seconds, period_s, a.priority, thresholds)
    print(json.dumps(asdict(r)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
