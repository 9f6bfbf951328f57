"""``execute --preview``: the run on the wrist's twin in simulated time, from where the wrist
rests; deterministic, logged as a preview, its exit code the predicted run's, and the same
figures as the run itself on the same emulated wrist."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.config.schema import Profile
from spm_console.errors import ExitCode
from spm_console.motion.logs.mcap_log import MCAP_NAME
from spm_console.motion.logs.runlog import RunData, load_run
from spm_console.motion.plans import synthetic_plan
from spm_console.store.plan_file import save_plan
from tests.support.exec_helpers import PAPER_START

GOAL = np.array([100.0, 120.0, 110.0])


@pytest.fixture(scope="module")
def plan_file(tmp_path_factory: pytest.TempPathFactory, agile: Profile) -> Path:
    path = tmp_path_factory.mktemp("plans") / "short.json"
    save_plan(synthetic_plan(agile, PAPER_START, GOAL, 1.5), path)
    return path


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, dict]:  # type: ignore[type-arg]
    code = main(list(argv))
    got = capsys.readouterr()
    out = got.out.strip().splitlines()
    assert len(out) == 1, out
    return code, {**json.loads(out[0]), "_stderr": got.err}


def _closest_links_one_by_one(profile: Profile, run: RunData) -> float:
    """The reference for the preview's closest links: the FK of each plan sample tracked
    from the sample before it, one at a time, and the links' distances there (mm)."""
    from spm_console.config.models import link_model_of, model_of

    model, links = model_of(profile), link_model_of(profile)
    keep = np.array([p in ("plan", "settle") for p in run.phase])
    theta = np.radians(run.vec("meas")[keep])
    closest, prev = np.inf, (model.theta_home, np.eye(3))
    for th in theta:
        r = model.track(th, *prev)
        assert r.ok and r.pose is not None, r.reason
        prev = (th, r.pose.R)
        closest = min(closest, float(links.min_distance(model.u, model.geom.w(th),
                                                        r.pose.v)[0]))
    return closest


def test_a_preview_predicts_the_run_and_says_it_is_one(
        plan_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], agile: Profile) -> None:
    argv = ("execute", "--plan", str(plan_file), "--sim", "--plant", "ideal", "--json")
    code, d = _run(capsys, *argv, "--preview", "--logs", str(tmp_path / "a"))
    assert code == 0 and d["preview"] is True and d["outcome"] == "completed"
    assert d["plant"] == "ideal" and d["homing"]["outcome"] == "completed"
    np.testing.assert_allclose(d["final_error_deg"], np.asarray(d["final_deg"]) - GOAL,
                               atol=1e-9)
    assert max(abs(x) for x in d["final_error_deg"]) < 0.15
    assert d["min_margin_deg"] > 0.0 and d["min_link_mm"] > d["link_limit_mm"]
    assert d["simulated_s"] > 1.5
    run, homing = load_run(d["log_dir"]), load_run(d["homing"]["log_dir"])
    for r in (run, homing):
        assert r.meta["preview"] is True and r.meta["clock"] == "simulated"
        assert not (r.path / MCAP_NAME).exists()  # a prediction: its samples, no MCAP
    assert d["min_link_mm"] == pytest.approx(_closest_links_one_by_one(agile, run), abs=1e-6)
    # the same preview again: the same samples, byte for byte
    _, d2 = _run(capsys, *argv, "--preview", "--logs", str(tmp_path / "b"))
    assert (Path(d["log_dir"]) / "samples.csv").read_bytes() == \
        (Path(d2["log_dir"]) / "samples.csv").read_bytes()
    # the run itself on the same emulated wrist, in simulated time: what the preview said
    code, real = _run(capsys, *argv, "--logs", str(tmp_path / "c"))
    assert code == 0 and "preview" not in load_run(real["log_dir"]).meta
    assert (Path(real["log_dir"]) / MCAP_NAME).is_file()
    assert real["final_deg"] == d["final_deg"]
    np.testing.assert_allclose(real["stats"]["tracking_rms_per_joint_deg"],
                               d["tracking_rms_per_joint_deg"], atol=0.02)


def test_a_preview_that_stops_exits_with_the_predicted_stop(
        plan_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, d = _run(capsys, "execute", "--plan", str(plan_file), "--sim", "--plant", "ideal",
                   "--json", "--preview", "--fault", "stall:2@0.5", "--logs", str(tmp_path))
    assert code == int(ExitCode.STOP_TRACKING) == d["exit_code"]
    assert d["preview"] is True and d["outcome"] == "stopped"
    assert "the preview stopped" in d["_stderr"]


def test_a_preview_starts_where_the_emulated_wrist_rests(
        plan_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    start = [float(x) for x in PAPER_START]
    code, d = _run(capsys, "execute", "--plan", str(plan_file), "--sim", "--plant", "ideal",
                   "--json", "--preview", "--skip-homing", "a preview from the plan's start",
                   "--sim-start", *(f"{x:g}" for x in start), "--logs", str(tmp_path))
    assert code == 0 and d["homing"] is None and d["start_deg"] == start
    assert load_run(d["log_dir"]).meta["homing"].startswith("skipped")


def test_follow_previews_a_timed_target_file_and_refuses_live_targets(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    csv = tmp_path / "targets.csv"
    csv.write_text("t,a,b,c\n0,135,135,135\n0.5,140,130,138\n1.5,132,138,130\n")
    code, d = _run(capsys, "follow", "--targets", str(csv), "--sim", "--plant", "ideal",
                   "--json", "--preview", "--logs", str(tmp_path / "logs"))
    assert code == 0 and d["preview"] is True and d["outcome"] == "completed"
    assert d["targets"] == str(csv)
    assert max(abs(x) for x in d["final_error_deg"]) < 0.3  # settled on the last target
    assert d["min_margin_deg"] > 0.0
    assert load_run(d["log_dir"]).meta["preview"] is True
    assert main(["follow", "--udp", "9999", "--sim", "--preview"]) == int(ExitCode.BAD_INPUT)
    assert "timed target file" in capsys.readouterr().err


def test_the_physical_twin_predicts_each_motors_peak_current(
        plan_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The physical twin's motors draw current (the ideal servos model none); it is told
    per joint, below the MX-106's stall current at its supply, and lands in the log."""
    from spm_console.config.schema import Plant
    from spm_console.description.mjcf import plant_params

    code, d = _run(capsys, "execute", "--plan", str(plan_file), "--sim", "--plant", "physical",
                   "--json", "--preview", "--logs", str(tmp_path))
    assert code == 0 and d["plant"] == "physical", d
    peak = np.asarray(d["peak_current_a"], float)
    p = plant_params(Plant())
    assert peak.shape == (3,) and (peak > 0.05).all(), peak
    assert (peak < p.supply_v / p.resistance_ohm).all(), peak
    told = [e for e in load_run(d["log_dir"]).events if e["event"] == "peak_current"]
    assert len(told) == 1 and told[0]["source"] == "emulated wrist"
    assert max(told[0]["peak_current_a"]) <= peak.max()
