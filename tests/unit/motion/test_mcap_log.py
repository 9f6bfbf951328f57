"""The MCAP writer on awkward run folders: events without a usable time, a failed read, a
measured θ no wrist reaches, a writer that fails half-way (nothing half-written is left)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from spm_console.config.schema import Profile
from spm_console.motion.logs import mcap_log
from spm_console.motion.logs.mcap_log import LIMIT_SLACK_DEG
from spm_console.motion.logs.runlog import RunLog
from spm_console.motion.sample import Sample


def _run(tmp_path: Path, agile: Profile, absurd: float | None = None) -> Path:
    """Five rows about home; row 2's read failed, or with ``absurd`` it measured that θ2."""
    log = RunLog.create("execute", agile.name, agile.digest(), [], root=tmp_path)
    home = np.array(agile.home.theta_deg, float)
    for k in range(5):
        meas = home + 0.1 * k if k != 2 else np.full(3, np.nan)  # row 2: the read failed
        if k == 2 and absurd is not None:
            meas = home + np.array([0.0, absurd - home[1], 0.0])
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
    out = mcap_log.write_run_mcap(run, agile).path
    with out.open("rb") as fh:
        counts: dict[str, int] = {}
        for _s, channel, _m in make_reader(fh).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    assert counts["/spm/reference"] == 5 and counts["/spm/measured"] == 4
    assert counts["/joint_states"] == 4 and counts["/spm/events"] == 3


def _topics(path: Path) -> dict[str, int]:
    from mcap.reader import make_reader

    counts: dict[str, int] = {}
    with path.open("rb") as fh:
        for _s, channel, _m in make_reader(fh).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    return counts


#: Continuation steps a five-row run about home needs, with room to spare.
STEP_BUDGET = 100


@pytest.mark.parametrize("absurd", [1e10, 1e308, -1e308, 400.0, 160.0 + LIMIT_SLACK_DEG + 0.5])
def test_a_measured_angle_no_wrist_reaches_gets_no_pose(
        tmp_path: Path, agile: Profile, monkeypatch: pytest.MonkeyPatch, absurd: float) -> None:
    """A corrupt sample (beyond the servo limits and their slack) is published as measured but
    gets no FK: the continuation never walks towards it (it did, for hours, at 1e10°)."""
    from spm_console.core.kinematics import model as model_module

    run = _run(tmp_path, agile, absurd)
    steps: list[int] = []
    real = model_module.continuation_step

    def step(*a: object, **k: object) -> object:
        steps.append(1)
        if len(steps) > STEP_BUDGET:
            raise AssertionError("the FK follows the absurd sample")
        return real(*a, **k)  # type: ignore[arg-type]

    monkeypatch.setattr(model_module, "continuation_step", step)
    done = mcap_log.write_run_mcap(run, agile)
    assert (done.beyond_limits, done.first_beyond) == (1, 3)  # the CSV's third sample
    counts = _topics(done.path)
    assert counts["/spm/measured"] == 5
    assert counts["/joint_states"] == counts["/spm/platform"] == counts["/tf"] == 4


def test_an_angle_just_past_the_limits_is_still_posed(tmp_path: Path, agile: Profile) -> None:
    """A run stopped for leaving the servo limits logs the sample beyond them: it has its pose."""
    hi = max(j.max_deg for j in agile.bus.joints)
    done = mcap_log.write_run_mcap(_run(tmp_path, agile, hi + 0.5), agile)
    assert done.beyond_limits == 0 and done.first_beyond is None


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


def test_logs_export_names_the_sample_it_left_unposed(
        tmp_path: Path, agile: Profile, capsys: pytest.CaptureFixture[str]) -> None:
    from spm_console.cli.main import main

    run = _run(tmp_path, agile, 1e10)
    assert main(["logs", "export", "--mcap", str(run), "--json"]) == 0
    captured = capsys.readouterr()
    rec = json.loads(captured.out)
    assert rec["samples_beyond_limits"] == 1 and rec["first_beyond_limits"] == 3
    assert "the first: sample 3" in captured.err and "servo limits" in captured.err
