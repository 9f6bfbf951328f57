"""Summary statistics of an executed run (timing, bus, tracking), from its samples.

:class:`RunStats` is what :class:`~spm_console.motion.segments.ExecutionResult` carries;
:meth:`RunStats.to_dict` is its form in run logs and ``--json`` output (same keys).
Times in ms where the name says so, angles in degrees.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

from spm_console.motion.sample import Sample

NAN = float("nan")


@dataclass(frozen=True)
class Spread:
    """Median, 99th percentile and maximum of a per-cycle quantity."""

    p50: float
    p99: float
    max: float


@dataclass(frozen=True)
class BusTime:
    """Bus time per cycle (write + read), ms."""

    mean: float
    p99: float
    max: float


@dataclass(frozen=True)
class ReadOffset:
    """How long after the cycle start the position was read, ms."""

    p50: float
    max: float


@dataclass(frozen=True)
class StopTiming:
    """When a stop was detected, its action issued and done (s from the loop start)."""

    kind: str
    detected_t: float
    k: int
    issued_t: float | None = None
    done_t: float | None = None


@dataclass(frozen=True)
class ModelHealth:
    """The servo model against the measurement, per joint, and the verdict: a largest error
    above the profile's residual bound says the model looks wrong for this servo."""

    rms_per_joint_deg: tuple[float, ...]
    max_per_joint_deg: tuple[float, ...]
    bound_deg: float
    """The profile's ``servo.residual_bound_deg``, or :data:`DEFAULT_TICKS` encoder ticks
    for a model without one (the model's quantization alone reaches about one)."""
    identified_bound: bool
    """True when the bound is the profile's (measured on held-out data)."""
    exceeds: bool
    """Some joint's largest error is above the bound: the model looks wrong."""

    def text(self) -> str:
        """One line for people."""
        per = ", ".join(f"{r:.3f}/{m:.3f}" for r, m in zip(self.rms_per_joint_deg,
                                                           self.max_per_joint_deg, strict=True))
        bound = (f"the profile's residual bound {self.bound_deg:.2f}°" if self.identified_bound
                 else f"{self.bound_deg:.2f}° ({DEFAULT_TICKS} encoder ticks; the profile has no "
                      "identified residual bound)")
        head = f"model vs measured per joint, RMS/max: {per}°"
        if not self.exceeds:
            return f"{head}; within {bound}"
        return (f"{head}; above {bound}: the servo model looks wrong for this servo; run the "
                "identification experiment (spm-console identify --experiment --out NEW.toml)")


DEFAULT_TICKS = 3
"""Encoder ticks the model may be off by when the profile has no identified residual bound:
the goal and the reading are each quantized to a tick."""


def model_health(samples: Sequence[Sample], bound_deg: float | None, tick_deg: float
                 ) -> ModelHealth | None:
    """The model's errors at the samples read, and the verdict (None when nothing was read)."""
    ok = np.array([s.read_ok for s in samples], bool)
    if not ok.any():
        return None
    err = np.abs(np.array([s.measured_deg for s in samples])[ok]
                 - np.array([s.predicted_deg for s in samples])[ok])
    bound = DEFAULT_TICKS * tick_deg if bound_deg is None else float(bound_deg)
    mx = err.max(axis=0)
    return ModelHealth(tuple(float(x) for x in np.sqrt(np.mean(err ** 2, axis=0))),
                       tuple(float(x) for x in mx), bound, bound_deg is not None,
                       bool((mx > bound).any()))


@dataclass(frozen=True)
class RunStats:
    """What a run measured (no cycle ran: only ``samples`` = 0 and ``duration_s``)."""

    samples: int = 0
    duration_s: float = 0.0
    jitter_ms: Spread | None = None
    """|t(k) − t(k−1) − Ts| between consecutive cycle starts."""
    late_ms: Spread | None = None
    """How late each cycle started after its absolute deadline."""
    bus_ms: BusTime | None = None
    overruns: int = 0
    failed_reads: int = 0
    read_retries: int = 0
    tracking_rms_deg: float = NAN
    """Measured θ(k) vs the model at k·Ts (the paper's comparison), RMS over joints."""
    tracking_rms_per_joint_deg: tuple[float, ...] = ()
    tracking_max_deg: float = NAN
    timed_tracking_rms_deg: float = NAN
    """Per-sample max over joints against the model at the actual read instant (what the
    safety check uses), RMS."""
    timed_tracking_max_deg: float = NAN
    read_offset_ms: ReadOffset | None = None
    stale_replies: int = 0
    """Late or unasked-for status packets the bus discarded during the run."""
    comm_retries: int = 0
    comm_failed_cycles: int = 0
    stop: StopTiming | None = None
    model: ModelHealth | None = None
    """The servo model against the measurement (None when nothing was read)."""

    def to_dict(self) -> dict[str, object]:
        """The run-log / JSON form (the keys of the fields; absent parts left out)."""
        d = asdict(self)
        d["tracking_rms_per_joint_deg"] = list(self.tracking_rms_per_joint_deg)
        if self.samples == 0:
            keep = {"samples", "duration_s", "stale_replies", "comm_retries",
                    "comm_failed_cycles", "stop"}
            d = {k: v for k, v in d.items() if k in keep}
        return {k: v for k, v in d.items() if v is not None}


def _pct(x: np.ndarray, q: float) -> float:
    return float(np.percentile(x, q)) if x.size else NAN


def _max(x: np.ndarray, empty: float = NAN) -> float:
    return float(x.max()) if x.size else empty


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else NAN


def run_stats(samples: Sequence[Sample], ts: float) -> RunStats:
    """Jitter (ms), bus time per cycle (ms), retries, tracking vs model (deg) of a run."""
    n = len(samples)
    if n == 0:
        return RunStats(samples=0, duration_s=0.0)
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
    per_joint = tuple(float(x) for x in np.sqrt(np.mean(err**2, axis=0))) if err.size else ()
    return RunStats(
        samples=n, duration_s=n * ts,
        jitter_ms=Spread(_pct(jit, 50), _pct(jit, 99), _max(jit)),
        late_ms=Spread(_pct(late, 50), _pct(late, 99), _max(late)),
        bus_ms=BusTime(float(bus.mean()), _pct(bus, 99), _max(bus)),
        overruns=int((late > ts * 1e3).sum()),
        failed_reads=int((~ok).sum()),
        read_retries=int(sum(s.retries for s in samples)),
        tracking_rms_deg=_rms(err),
        tracking_rms_per_joint_deg=per_joint,
        tracking_max_deg=_max(np.abs(err)),
        timed_tracking_rms_deg=_rms(timed),
        timed_tracking_max_deg=_max(timed),
        read_offset_ms=ReadOffset(_pct(offs, 50), _max(offs, 0.0)),
    )


def stale_replies(bus: object) -> int:
    """The bus's count of stale status packets so far (late replies to earlier requests, or
    replies nothing asked for; see ``DynamixelBus.stale_replies``); 0 when it keeps none."""
    return int(getattr(bus, "stale_replies", 0))


@dataclass(frozen=True)
class SettleOutcome:
    """How a run's settling at its goal ended (degrees)."""

    settled: bool
    error_deg: tuple[float, float, float]
    """Goal − measured position when the settling ended, per joint."""
    tolerance_deg: float
    duration_s: float
    refused_shifts: int
    """Shifts not (wholly) taken: the shifted goal would have left the certified set (as
    relaxed by the region margin for measured positions) or the servo limits."""

    def text(self) -> str:
        """One line for the operator: empty when it settled."""
        if self.settled:
            return ""
        j = int(np.argmax(np.abs(self.error_deg)))
        line = (f"did not settle within {self.duration_s:g} s: joint {j + 1} rests "
                f"{abs(self.error_deg[j]):.2f}° from its goal (tolerance "
                f"{self.tolerance_deg:g}°)")
        if self.refused_shifts:
            line += (f"; {self.refused_shifts} goal shifts refused, which would have left the "
                     "workspace's certified set (with the region margin) or the servo limits "
                     "(a goal near their boundary)")
        return line

    def to_dict(self) -> dict[str, object]:
        return {"settled": self.settled, "error_deg": list(self.error_deg),
                "tolerance_deg": self.tolerance_deg, "duration_s": self.duration_s,
                "refused_shifts": self.refused_shifts}
