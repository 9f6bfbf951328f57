"""Run log cost in the servo loop: one ``RunLog.sample`` call, and one flush to the OS.

The executor logs every cycle (Ts = 20 ms) from its own thread, so the log must stay
a small fraction of the period. ``samples.csv`` is flushed every ``FLUSH_EVERY``
rows (a SIGKILL then loses at most FLUSH_EVERY − 1 rows); the baseline is the former
setting, a flush every 10 rows. Measured on the log root's file system (a temporary
folder here); no fsync, so no disk wait is measured: a flush is one ``write`` call.
"""

from __future__ import annotations

import tempfile
import time

import numpy as np

from benchmarks.common import Row
from spm_console.motion.logs.runlog import FLUSH_EVERY, RunLog
from spm_console.motion.sample import Sample

#: Rows per measurement.
ROWS = 3000
#: Servo period the cost is compared with, s.
TS_S = 0.02


def _sample(k: int) -> Sample:
    v = np.array([100.0 + k * 1e-3, 120.123456, 110.5])
    return Sample(t=k * TS_S, k=k, phase="plan", reference_deg=v, measured_deg=v,
                  predicted_deg=v, predicted_velocity_degps=v, filtered_deg=v,
                  velocity_degps=v, fd_velocity_degps=v, tracking_error_deg=0.01,
                  bus_s=0.0012, late_s=0.0001, retries=0)


def per_sample_s(flush_every: int, rows: int = ROWS) -> tuple[float, float, float]:
    """(mean seconds per ``sample`` call flushing every ``flush_every`` rows, median and
    p99 seconds of one flush of ``flush_every`` full rows), writing ``rows`` rows."""
    samples = [_sample(k) for k in range(rows)]
    with tempfile.TemporaryDirectory() as tmp:
        log = RunLog.create("bench", "p", "h", [], root=tmp, flush_every=flush_every)
        t0 = time.perf_counter()
        for s in samples:
            log.sample(s)
        total = time.perf_counter() - t0
        log.finish("completed", 0, "", {})
        log = RunLog.create("bench", "p", "h", [], root=tmp, flush_every=rows + 1)
        flush_times = []
        for k, s in enumerate(samples, start=1):
            log.sample(s)
            if k % flush_every == 0:
                t1 = time.perf_counter()
                log.flush()
                flush_times.append(time.perf_counter() - t1)
        log.finish("completed", 0, "", {})
    return total / rows, float(np.median(flush_times)), float(np.percentile(flush_times, 99))


def run() -> list[Row]:
    ours, flush_s, flush_p99 = per_sample_s(FLUSH_EVERY)
    base, _, _ = per_sample_s(10)
    return [
        Row(f"runlog: sample() with flush every {FLUSH_EVERY}", ours * 1e6, "µs",
            target=f"< 2% of Ts ({0.02 * TS_S * 1e6:.0f} µs)", baseline=base * 1e6,
            passed=ours < 0.02 * TS_S, note="baseline: flush every 10 rows (before)"),
        Row(f"runlog: one flush of {FLUSH_EVERY} rows (median)", flush_s * 1e6, "µs", target="< 100 µs",
            passed=flush_s < 1e-4, note=f"p99 {flush_p99 * 1e6:.1f} µs"),
    ]
