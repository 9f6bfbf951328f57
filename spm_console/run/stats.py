"""Summary statistics of an executed run (timing, bus, tracking), from its samples."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from spm_console.run.sample import Sample


def _pct(x: np.ndarray, q: float) -> float:
    return float(np.percentile(x, q)) if x.size else float("nan")


def run_stats(samples: Sequence[Sample], ts: float) -> dict[str, Any]:
    """Jitter (ms), bus time per cycle (ms), retries, tracking vs model (deg) of a run.

    ``tracking_*`` compare the measured θ(k) with the model at k·Ts (the plan's simulated
    positions, the paper's comparison); ``timed_tracking_*`` use the per-sample max over
    joints against the model at the actual read instant (what the safety check uses).

    Period jitter is |t(k) − t(k−1) − Ts| between consecutive cycle starts;
    lateness is how late each cycle started after its absolute deadline.
    """
    n = len(samples)
    out: dict[str, Any] = {"samples": n, "duration_s": n * ts}
    if n == 0:
        return out
    t = np.array([s.t for s in samples])
    late = np.array([s.late_s for s in samples]) * 1e3
    bus = np.array([s.bus_s for s in samples]) * 1e3
    jit = np.abs(np.diff(t) - ts) * 1e3
    ok = np.array([s.read_ok for s in samples])
    meas = np.array([s.measured_deg for s in samples])
    pred = np.array([s.predicted_deg for s in samples])
    err = (meas - pred)[ok]
    timed = np.array([s.tracking_error_deg for s in samples])[ok]
    offs = np.array([s.read_offset_s for s in samples])[ok] * 1e3
    out.update(
        jitter_ms={"p50": _pct(jit, 50), "p99": _pct(jit, 99),
                   "max": float(jit.max()) if jit.size else float("nan")},
        late_ms={"p50": _pct(late, 50), "p99": _pct(late, 99), "max": float(late.max())},
        bus_ms={"mean": float(bus.mean()), "p99": _pct(bus, 99), "max": float(bus.max())},
        overruns=int((late > ts * 1e3).sum()),
        failed_reads=int((~ok).sum()),
        read_retries=int(sum(s.retries for s in samples)),
        tracking_rms_deg=float(np.sqrt(np.mean(err**2))) if err.size else float("nan"),
        tracking_rms_per_joint_deg=(np.sqrt(np.mean(err**2, axis=0)).tolist()
                                    if err.size else []),
        tracking_max_deg=float(np.abs(err).max()) if err.size else float("nan"),
        timed_tracking_rms_deg=float(np.sqrt(np.mean(timed**2))) if timed.size else float("nan"),
        timed_tracking_max_deg=float(timed.max()) if timed.size else float("nan"),
        read_offset_ms={"p50": _pct(offs, 50), "max": float(offs.max()) if offs.size else 0.0},
    )
    return out


def stale_replies(bus: object) -> int:
    """The bus's count of stale status packets so far (late replies to earlier requests, or
    replies nothing asked for; see ``DynamixelBus.stale_replies``); 0 when it keeps none."""
    return int(getattr(bus, "stale_replies", 0))
