"""Run folders with a chosen outcome, written by the run-log writer itself (no motion)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from spm_console.motion.logs.runlog import RunLog
from spm_console.motion.sample import Sample

TS = 0.02
"""Period of the written samples, s."""

START = (135.0, 135.0, 135.0)
GOAL = (95.0, 110.0, 105.0)
"""The plan of every written run, deg."""


def sample(k: int, ok: bool = True, retries: int = 0, late_s: float = 1e-4,
           stale: int = 0, jitter_s: float = 0.0) -> Sample:
    """Cycle k of a motion from 100° + k (NaN measured when ``ok`` is False)."""
    th = np.full(3, 100.0 + k)
    meas = th - 0.1 if ok else np.full(3, np.nan)
    return Sample(t=k * TS + jitter_s, k=k, phase="plan", reference_deg=th, measured_deg=meas,
                  predicted_deg=th, predicted_velocity_degps=np.full(3, 50.0),
                  filtered_deg=th, velocity_degps=np.full(3, 49.0),
                  fd_velocity_degps=np.full(3, 48.0),
                  tracking_error_deg=0.1 if ok else float("nan"), bus_s=1e-3, late_s=late_s,
                  retries=retries, stale_replies=stale)


def plans(kind: str = "mvn", approach: bool = True) -> list[dict[str, Any]]:
    """meta.json plan summaries as an execute writes them (an approach move, then the plan)."""
    main = {"kind": kind, "phase": "plan", "N": 50, "Ts": TS, "duration_s": 1.0,
            "first_reference_deg": list(START), "last_reference_deg": list(GOAL)}
    first = {"kind": "homing", "phase": "approach", "N": 10, "Ts": TS, "duration_s": 0.2,
             "first_reference_deg": [130.0, 130.0, 130.0], "last_reference_deg": list(START)}
    return [first, main] if approach else [main]


def write_run(root: Path, outcome: str, exit_code: int = 0, message: str = "",
              stop_kind: str | None = None, rows: int = 20, kind: str = "execute",
              plan_kind: str = "mvn") -> RunLog:
    """A finished run folder under ``root``: ``rows`` samples, a stop event and the stop in
    the statistics when ``stop_kind`` is given. ``outcome`` 'killed' leaves it 'running'
    as a writer killed mid-run does (its process id is then made a dead one)."""
    log = RunLog.create(kind, "agile_wrist", "h", plans(plan_kind), root=root)
    for k in range(rows):
        log.sample(sample(k))
    stats: dict[str, Any] = {"samples": rows, "duration_s": rows * TS}
    if stop_kind is not None:
        t = rows * TS
        log.event("fault", t, kind=stop_kind, message=message)
        log.event("stop", t, kind=stop_kind, exit_code=exit_code, detected_t=t)
        stats["stop"] = {"kind": stop_kind, "detected_t": t, "k": rows}
    if outcome == "killed":
        log.flush()
        log.close()
        # written before a reboot, by a process started at another time: the writer is gone
        log.meta["process"] = {**log.meta["process"], "boot_id": "another boot",
                               "start_ticks": -1}
        (log.path / "meta.json").write_text(json.dumps(log.meta))
        return log
    log.finish(outcome, exit_code, message, stats)
    return log
