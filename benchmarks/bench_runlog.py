"""Run log cost in the servo loop: one ``RunLog.sample`` call, and one flush to the OS.

The executor logs every cycle (Ts = 20 ms) from its own thread, so the log must stay
a small fraction of the period. ``samples.csv`` is flushed every ``FLUSH_EVERY``
rows (a SIGKILL then loses at most FLUSH_EVERY − 1 rows); the baseline is the former
setting, a flush every 10 rows. Measured on the log root's file system (a temporary
folder here); no fsync, so no disk wait is measured: a flush is one ``write`` call.

The MCAP beside the CSV is written from the finished files, after the loop (target of the
lab-tools issue: a 6 s run's MCAP ≤ 2× its CSV, ≤ 50 µs per sample in the loop): its size
against the CSV's, and the time per sample it takes after the run, on a 6 s run about home at
the profile's Ts.
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


def mcap_of_a_run(seconds: float = 6.0) -> tuple[int, int, float, int]:
    """(MCAP bytes, CSV bytes, seconds to write the MCAP, rows) of a logged run of ``seconds``
    at the default profile's Ts: each joint swinging ±10° about home, the measurement the
    model plus a tick of noise, one event."""
    from spm_console.config.load import load_profile
    from spm_console.motion.logs.mcap_log import write_run_mcap

    profile = load_profile("profiles/agile_wrist.toml")
    ts = profile.servo.ts_s
    home = np.array(profile.home.theta_deg, float)
    rng = np.random.default_rng(0)
    n = round(seconds / ts) + 1
    with tempfile.TemporaryDirectory() as tmp:
        log = RunLog.create("bench", profile.name, profile.digest(), [], root=tmp)
        log.event("start", 0.0, cycles=n)
        for k in range(n):
            t = k * ts
            ref = home + 10.0 * np.sin(2 * np.pi * t / seconds + np.array([0.0, 2.0, 4.0]))
            pred = home + 10.0 * np.sin(2 * np.pi * (t - 0.03) / seconds + np.array([0.0, 2.0, 4.0]))
            meas = pred + rng.normal(0.0, 0.05, 3)
            vel = (ref - pred) / 0.03
            log.sample(Sample(t=t, k=k, phase="plan", reference_deg=ref, measured_deg=meas,
                              predicted_deg=pred, predicted_velocity_degps=vel,
                              filtered_deg=meas, velocity_degps=vel, fd_velocity_degps=vel,
                              tracking_error_deg=float(np.abs(meas - pred).max()),
                              bus_s=0.0012, late_s=0.0001, retries=0, read_offset_s=0.0004))
        log.finish("completed", 0, "", {})
        t0 = time.perf_counter()
        out = write_run_mcap(log.path, profile).path
        took = time.perf_counter() - t0
        return out.stat().st_size, (log.path / "samples.csv").stat().st_size, took, n


def run() -> list[Row]:
    ours, flush_s, flush_p99 = per_sample_s(FLUSH_EVERY)
    base, _, _ = per_sample_s(10)
    mcap_bytes, csv_bytes, mcap_s, rows = mcap_of_a_run()
    return [
        Row("runlog: MCAP size of a 6 s run / its CSV", mcap_bytes / csv_bytes, "×", "≤ 2×",
            passed=mcap_bytes <= 2 * csv_bytes,
            note=f"{mcap_bytes} B against {csv_bytes} B, {rows} samples (ZSTD chunks); topics: "
                 "joint states of every joint, reference, measured, model, error, platform "
                 "quaternion and TF, events"),
        Row("runlog: MCAP work in the servo loop, per sample", 0.0, "µs", "≤ 50 µs", passed=True,
            note=f"none: written from the finished files after the loop, "
                 f"{mcap_s * 1e6 / rows:.0f} µs per sample then ({mcap_s:.2f} s for the run, "
                 "FK of every measured θ included)"),
        Row(f"runlog: sample() with flush every {FLUSH_EVERY}", ours * 1e6, "µs",
            target=f"< 2% of Ts ({0.02 * TS_S * 1e6:.0f} µs)", baseline=base * 1e6,
            passed=ours < 0.02 * TS_S, note="baseline: flush every 10 rows (before)"),
        Row(f"runlog: one flush of {FLUSH_EVERY} rows (median)", flush_s * 1e6, "µs", target="< 100 µs",
            passed=flush_s < 1e-4, note=f"p99 {flush_p99 * 1e6:.1f} µs"),
    ]
