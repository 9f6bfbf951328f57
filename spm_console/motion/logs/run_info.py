"""What a run log says about its run, as one typed record: outcome, exit code, why it
stopped, when and how long it ran, which plan it executed from where to where.

Read from ``meta.json`` (see :mod:`spm_console.motion.logs.runlog`); the stop kind comes from the
run's statistics there, else from the ``stop`` event of ``events.jsonl`` when the events
are at hand, else from the exit code. A log is data from disk: every field is checked and
an absent or malformed one is ``None`` (never an exception). Angles in degrees, times in
seconds.
"""

from __future__ import annotations

import datetime as dt
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from spm_console.errors import ExitCode

OUTCOMES: tuple[str, ...] = ("completed", "stopped", "refused", "error", "killed", "running")
"""Outcomes a run log can report (``killed``: marked running, its writer is gone)."""

STOP_LABELS: dict[str, str] = {
    "estop": "E-stop",
    "comm": "communication lost",
    "tracking": "tracking error",
    "hw_error": "servo hardware error",
    "region": "left the certified region",
    "limit": "servo limit",
}
"""Operator wording of the executor's stop kinds (``run.safety.StopKind``)."""

STOP_KIND_BY_EXIT: dict[int, str] = {
    int(ExitCode.STOP_ESTOP): "estop",
    int(ExitCode.STOP_TRACKING): "tracking",
    int(ExitCode.STOP_COMM): "comm",
    int(ExitCode.STOP_HW_ERROR): "hw_error",
    int(ExitCode.STOP_REGION): "region",
    int(ExitCode.STOP_LIMIT): "limit",
}
"""The stop kind an exit code stands for (the inverse of ``run.safety.EXIT_CODES``)."""

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class RunPlan:
    """The plan a run executed (for a homing run, its homing move)."""

    kind: str
    """'mvn', 'mintime', 'homing', … as the plan summary in meta.json names it."""
    first_reference_deg: Vec3 | None
    """θ*(0), deg (a run log written before 0.2.0 calls it ``start_deg``)."""
    last_reference_deg: Vec3 | None
    """θ*(N), deg (before 0.2.0: ``goal_deg``)."""
    duration_s: float | None
    after_approach: bool
    """An approach move from where the wrist was to the plan's start came first."""


@dataclass(frozen=True)
class RunInfo:
    """One run, from its log."""

    name: str
    """The run folder's name."""
    kind: str
    """What ran: 'execute', 'home', … ('?' when the log does not say)."""
    outcome: str
    """One of :data:`OUTCOMES`, or what the log says when it is none of them."""
    exit_code: int | None
    message: str
    stop_kind: str | None
    """Why a stopped run stopped (a key of :data:`STOP_LABELS`); None otherwise."""
    started: dt.datetime | None
    ended: dt.datetime | None
    loop_s: float | None
    """How long the servo loop ran, s (cycles × Ts)."""
    samples: int | None
    plan: RunPlan | None
    bus: str | None
    preview: bool = False
    """A preview: the run made on the wrist's twin in simulated time (nothing moved)."""

    @property
    def duration_s(self) -> float | None:
        """Wall time from the log's start to its end, s (None while running or killed)."""
        if self.started is None or self.ended is None:
            return None
        return max(0.0, (self.ended - self.started).total_seconds())

    @property
    def stop_label(self) -> str:
        """'E-stop', 'communication lost', … for a stopped run; '' otherwise."""
        if self.stop_kind is None:
            return ""
        return STOP_LABELS.get(self.stop_kind, self.stop_kind)

    @property
    def reason(self) -> str:
        """Why the run ended as it did: the stop's label for a stopped run ('E-stop', …),
        the log's message for any other run that did not complete (a refusal's reason, an
        error, a killed writer); '' for a completed or running one."""
        if self.outcome == "stopped":
            return self.stop_label or self.message
        if self.outcome in ("completed", "running"):
            return ""
        return self.message


def _str(x: Any) -> str | None:
    return x if isinstance(x, str) else None


def _int(x: Any) -> int | None:
    if isinstance(x, bool) or not isinstance(x, int | float):
        return None
    if isinstance(x, float) and (not math.isfinite(x) or x != int(x)):
        return None
    return int(x)


def _float(x: Any) -> float | None:
    if isinstance(x, bool) or not isinstance(x, int | float):
        return None
    return float(x) if math.isfinite(x) else None


def _vec3(x: Any) -> Vec3 | None:
    if not isinstance(x, Sequence) or isinstance(x, str) or len(x) != 3:
        return None
    v = [_float(c) for c in x]
    if any(c is None for c in v):
        return None
    return (float(v[0] or 0.0), float(v[1] or 0.0), float(v[2] or 0.0))


def _time(x: Any) -> dt.datetime | None:
    if not isinstance(x, str):
        return None
    try:
        t = dt.datetime.fromisoformat(x)
    except ValueError:
        return None
    return t if t.tzinfo is not None else t.replace(tzinfo=dt.UTC)


def _plan(plans: Any) -> RunPlan | None:
    """The entry of phase 'plan' (an execute), else the last one (a homing run's move)."""
    entries = [p for p in plans if isinstance(p, Mapping)] if isinstance(plans, list) else []
    if not entries:
        return None
    main = next((p for p in entries if p.get("phase") == "plan"), entries[-1])
    return RunPlan(
        kind=_str(main.get("kind")) or "?",
        first_reference_deg=_vec3(main.get("first_reference_deg", main.get("start_deg"))),
        last_reference_deg=_vec3(main.get("last_reference_deg", main.get("goal_deg"))),
        duration_s=_float(main.get("duration_s")),
        after_approach=any(p.get("phase") == "approach" for p in entries),
    )


def _stop_kind(meta: Mapping[str, Any], events: Sequence[Any] | None,
               outcome: str, exit_code: int | None) -> str | None:
    if outcome != "stopped":
        return None
    stats = meta.get("stats")
    stop = stats.get("stop") if isinstance(stats, Mapping) else None
    kind = _str(stop.get("kind")) if isinstance(stop, Mapping) else None
    if kind is None and events:
        kind = next((_str(e.get("kind")) for e in reversed(events)
                     if isinstance(e, Mapping) and e.get("event") == "stop"
                     and _str(e.get("kind"))), None)
    if kind is None and exit_code is not None:
        kind = STOP_KIND_BY_EXIT.get(exit_code)
    return kind


def run_info(name: str, meta: Mapping[str, object],
             events: Sequence[object] | None = None) -> RunInfo:
    """The typed record of run ``name`` from its meta.json (already checked for liveness,
    see ``runlog.with_liveness``) and, optionally, its events."""
    outcome = _str(meta.get("outcome")) or "?"
    exit_code = _int(meta.get("exit_code"))
    stats = meta.get("stats")
    loop_s = _float(stats.get("duration_s")) if isinstance(stats, Mapping) else None
    return RunInfo(
        name=name,
        kind=_str(meta.get("kind")) or "?",
        outcome=outcome,
        exit_code=exit_code,
        message=_str(meta.get("message")) or "",
        stop_kind=_stop_kind(meta, events, outcome, exit_code),
        started=_time(meta.get("start_time")),
        ended=_time(meta.get("end_time")),
        loop_s=loop_s,
        samples=_int(meta.get("samples")),
        plan=_plan(meta.get("plans")),
        bus=_str(meta.get("bus")),
        preview=meta.get("preview") is True,
    )
