"""The MCAP writer on awkward run folders: events without a usable time, a failed read, a
writer that fails half-way (nothing half-written is left)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from spm_console.config.schema import Profile
from spm_console.motion.logs import mcap_log
from spm_console.motion.logs.runlog import RunLog
from spm_console.motion.sample import Sample


def _run(tmp_path: Path, agile: Profile) -> Path:
    log = RunLog.create("execute", agile.name, agile.digest(), [], root=tmp_path)
    home = np.array(agile.home.theta_deg, float)
    for k in range(5):
        meas = home + 0.1 * k if k != 2 else np.full(3, np.nan)  # row 2: the read failed
        log.sample(Sample(t=0.02 * k, k=k, phase="plan", reference_deg=home + 0.1 * k,
                          measured_deg=meas, predicted_deg=home, predicted_velocity_degps=home * 0,
                          filtered_deg=home, velocity_degps=home * 0, fd_velocity_degps=home * 0,
                          tracking_error_deg=0.0, bus_s=0.001, late_s=0.0, retries=0))
    log.event("start", 0.0)
    log.finish("completed", 0, "", {})
    with (log.path / "events.jsonl").open("a") as fh:  # written by hand: no usable times
        fh.write(json.dumps({"event": "odd", "t": None}) + "\n")
        fh.write(json.dumps({"event": "odder"}) + "\n")
    return log.path


def test_rows_without_a_read_and_events_without_a_time(tmp_path: Path, agile: Profile) -> None:
    from mcap.reader import make_reader

    run = _run(tmp_path, agile)
    out = mcap_log.write_run_mcap(run, agile)
    with out.open("rb") as fh:
        counts: dict[str, int] = {}
        for _s, channel, _m in make_reader(fh).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    assert counts["/spm/reference"] == 5 and counts["/spm/measured"] == 4
    assert counts["/joint_states"] == 4 and counts["/spm/events"] == 3


def test_a_failed_write_leaves_nothing_behind(tmp_path: Path, agile: Profile,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    run = _run(tmp_path, agile)

    def broken(*_a: object, **_k: object) -> None:
        raise RuntimeError("disk full (simulated)")

    monkeypatch.setattr(mcap_log.Writer, "finish", broken)
    with pytest.raises(RuntimeError):
        mcap_log.write_run_mcap(run, agile)
    assert sorted(p.name for p in run.iterdir()) == ["events.jsonl", "meta.json", "samples.csv"]


def test_a_long_run_defers_its_mcap_to_logs_export(tmp_path: Path, agile: Profile,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    from spm_console.motion.logs.runlog import load_run

    run = _run(tmp_path, agile)
    monkeypatch.setattr(mcap_log, "MAX_ROWS_AT_FINISH", 4)
    mcap_log.mcap_beside(agile)(run)
    assert not (run / mcap_log.MCAP_NAME).exists() and not (run / "metadata.yaml").exists()
    (ev,) = [e for e in load_run(run).events if e["event"] == "mcap_deferred"]
    assert ev["rows"] == 5 and "logs export --mcap" in ev["message"]
    monkeypatch.setattr(mcap_log, "MAX_ROWS_AT_FINISH", 5)
    mcap_log.mcap_beside(agile)(run)
    assert (run / mcap_log.MCAP_NAME).is_file() and (run / "metadata.yaml").is_file()
