"""``latency``: how late this machine wakes the servo loop, per CPU, against the profile's
reply timeout and communication-loss window (see :mod:`spm_console.system.host_latency`)."""

from __future__ import annotations

import argparse
from dataclasses import asdict
from typing import Any

from spm_console.cli.common import add_common, emit, info, number, profile_of
from spm_console.input_rules import finite_number
from spm_console.system.host_latency import MAX_SECONDS, THRESHOLDS_MS, CpuLatency, measure

#: Verdicts, worst last.
VERDICTS = {
    "fit": "no wake-up came as late as the reply timeout",
    "late_reads": "wake-ups later than the reply timeout: expect some late or retried reads",
    "comm_loss_risk": "a stall as long as the communication-loss window: a run can stop with "
                      "\"communication lost\" on this machine",
}


def register(sub: Any) -> None:
    p = sub.add_parser("latency", help="measure how late this machine wakes a real-time thread "
                                       "(per CPU), against the profile's bus timing (not while "
                                       "the wrist moves: it loads the machine a little)")
    add_common(p)
    p.add_argument("--seconds", type=number, default=10.0,
                   help=f"how long to measure, s (0 < s ≤ {MAX_SECONDS:g}; default 10)")
    p.set_defaults(func=cmd_latency)


def verdict(cpus: list[CpuLatency], timeout_ms: float, window_ms: float) -> str:
    """"fit", "late_reads" or "comm_loss_risk" (:data:`VERDICTS`) from the longest stall."""
    worst = max((c.max_ms for c in cpus), default=0.0)
    if worst >= window_ms:
        return "comm_loss_risk"
    return "late_reads" if worst >= timeout_ms else "fit"


def cmd_latency(args: argparse.Namespace) -> int:
    seconds = finite_number(args.seconds, "--seconds", 0.0, MAX_SECONDS, lo_open=True, unit="s")
    prof = profile_of(args)
    timeout_ms = prof.bus.timeout_s * 1e3
    window_ms = prof.safety.comm_failures * prof.servo.ts_s * 1e3
    info(f"measuring every allowed CPU for {seconds:g} s (the servo loop's priority, 1 ms sleeps)")
    cpus = measure(seconds, thresholds_ms=sorted({*THRESHOLDS_MS, timeout_ms, window_ms}))
    v = verdict(cpus, timeout_ms, window_ms)
    lines = [f"wake-up lateness of a real-time thread, {seconds:g} s per CPU "
             f"(profile {prof.name}: reply timeout {timeout_ms:g} ms, communication lost after "
             f"{prof.safety.comm_failures} cycles without a reply = {window_ms:g} ms)"]
    for c in cpus:
        lines.append(f"  CPU {c.cpu} ({c.scheduling}): {c.wakeups} wake-ups, p99 {c.p99_ms:.2f} ms, "
                     f"max {c.max_ms:.1f} ms; ≥ {timeout_ms:g} ms: {c.per_minute(timeout_ms):.0f}/min; "
                     f"≥ {window_ms:g} ms: {dict(c.late)[window_ms]}")
    lines.append(f"verdict: {v}: {VERDICTS[v]}")
    emit(args, {"ok": True, "profile": prof.name, "seconds": seconds, "reply_timeout_ms": timeout_ms,
                "comm_loss_window_ms": window_ms, "cpus": [asdict(c) for c in cpus], "verdict": v,
                "meaning": VERDICTS[v]}, "\n".join(lines))
    return 0
