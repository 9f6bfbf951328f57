"""``home``, ``execute`` and ``logs`` as operators and scripts run them (emulated bus)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.config.schema import Profile
from spm_console.errors import ExitCode
from spm_console.motion.logs.runlog import list_runs, load_run
from spm_console.motion.plans import synthetic_plan
from spm_console.store.plan_file import save_plan
from tests.support.exec_helpers import PAPER_START

GOAL = np.array([100.0, 120.0, 110.0])
#: At the plan's start, homing overridden (and logged): the fault and log tests start moving
#: the plan at once.
AT_START = ["--skip-homing", "test of faults", "--sim-start", *(f"{x:g}" for x in PAPER_START)]


@pytest.fixture(scope="module")
def plan_file(tmp_path_factory: pytest.TempPathFactory, agile: Profile) -> Path:
    path = tmp_path_factory.mktemp("plans") / "short.json"
    save_plan(synthetic_plan(agile, PAPER_START, GOAL, 1.5), path)
    return path


def _json(capsys: pytest.CaptureFixture[str]) -> dict:  # type: ignore[type-arg]
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1, out  # --json: exactly one object on stdout
    return json.loads(out[0])  # type: ignore[no-any-return]


def test_execute_sim_homes_first_then_approaches_and_completes(
        plan_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["execute", "--plan", str(plan_file), "--sim", "--json", "--logs", str(tmp_path)])
    d = _json(capsys)
    assert code == 0 and d["outcome"] == "completed" and d["exit_code"] == 0
    assert np.allclose(d["final_deg"], GOAL, atol=0.15)
    assert d["homing"]["outcome"] == "completed"
    home_run, run = load_run(d["homing"]["log_dir"]), load_run(d["log_dir"])
    assert home_run.meta["kind"] == "home" and home_run.meta["outcome"] == "completed"
    assert run.meta["homing"] == "done" and run.meta["outcome"] == "completed"
    assert [p["phase"] for p in run.meta["plans"]] == ["approach", "plan"]
    assert d["stats"]["samples"] == sum(p["N"] + 1 for p in run.meta["plans"])
    assert d["stats"]["tracking_rms_deg"] < 0.5
    assert run.meta["sim"] is True and run.meta["plans"][1]["source"] == str(plan_file)
    assert run.meta["profile"]["name"] == "agile_wrist" and len(run.meta["profile"]["hash"]) == 64


def test_skipping_homing_is_explicit_and_logged(plan_file: Path, tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["execute", "--plan", str(plan_file), "--json", "--logs", str(tmp_path),
                 "--sim", *AT_START])
    d = _json(capsys)
    assert code == 0 and d["homing"] == {"skipped": "test of faults"}
    run = load_run(d["log_dir"])
    assert run.meta["homing"] == "skipped by the operator: test of faults"
    assert [r.meta["kind"] for r in list_runs(tmp_path)] == ["execute"]  # no homing run
    for bad in ("   ", "x" * 201, "bell\x07"):
        code = main(["execute", "--plan", str(plan_file), "--sim", "--skip-homing", bad,
                     "--logs", str(tmp_path)])
        assert code == int(ExitCode.BAD_INPUT)
    assert "--skip-homing" in capsys.readouterr().err


@pytest.mark.parametrize(("fault", "code", "text"), [
    ("stall:2@0.4", ExitCode.STOP_TRACKING, "tracking error on joint 2"),
    # on the emulated bus (in simulated time: replies cannot be late) the reason names the
    # causes it can have, not the cable
    ("unplug@0.4", ExitCode.STOP_COMM, "on the emulated bus in simulated time, where no reply"),
    ("hwerror:1@0.4", ExitCode.STOP_HW_ERROR, "overload"),
])
def test_execute_fault_exit_codes(plan_file: Path, tmp_path: Path,
                                  capsys: pytest.CaptureFixture[str],
                                  fault: str, code: ExitCode, text: str) -> None:
    rc = main(["execute", "--plan", str(plan_file), "--sim", "--fault", fault, "--json",
               "--logs", str(tmp_path), *AT_START])
    captured = capsys.readouterr()
    d = json.loads(captured.out)
    assert rc == int(code) == d["exit_code"] and d["outcome"] == "stopped"
    assert text in d["message"] and text in captured.err  # the reason on stderr too
    assert d["stop"]["done_t"] - d["stop"]["detected_t"] <= 0.04
    run = load_run(d["log_dir"])
    assert run.meta["exit_code"] == int(code) and run.meta["faults"] == [fault]


def test_execute_adds_an_approach_move(plan_file: Path, tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["execute", "--plan", str(plan_file), "--sim", "--sim-start", "122", "90", "88",
               "--json", "--logs", str(tmp_path), "--skip-homing", "test of the approach"])
    d = _json(capsys)
    assert rc == 0, d["message"]
    run = load_run(d["log_dir"])
    assert [p["phase"] for p in run.meta["plans"]] == ["approach", "plan"]
    assert run.phase[0] == "approach" and run.phase[-1] == "plan"
    assert np.allclose(run.vec("meas")[0], [122, 90, 88], atol=0.1)
    rc = main(["execute", "--plan", str(plan_file), "--sim", "--sim-start", "122", "90", "88",
               "--no-approach", "--logs", str(tmp_path), "--skip-homing", "test"])
    assert rc == int(ExitCode.BAD_INPUT)
    assert "approach move disabled" in capsys.readouterr().err
    refused = load_run("last", tmp_path)
    assert refused.meta["outcome"] == "refused" and refused.rows == 0


def test_home_sim(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["home", "--sim", "--sim-start", "128", "140", "130", "--json",
               "--logs", str(tmp_path)])
    d = _json(capsys)
    assert rc == 0 and np.allclose(d["final_deg"], [135, 135, 135], atol=0.1)
    assert np.allclose(d["pose"]["n"], [0, 0, 1], atol=2e-3)
    assert np.allclose(d["start_deg"], [128, 140, 130], atol=0.1)


def test_home_sim_on_the_physical_wrist(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--plant physical: the MX-106 drives on the rigid-body wrist home it too; friction leaves
    it within a fraction of a degree of home (the ideal servos land within 0.1°)."""
    rc = main(["home", "--sim", "--plant", "physical", "--sim-start", "128", "140", "130",
               "--json", "--logs", str(tmp_path)])
    d = _json(capsys)
    assert rc == 0, d
    assert np.allclose(d["final_deg"], [135, 135, 135], atol=0.5)
    assert d["stats"]["tracking_rms_deg"] > 0.05  # the measured motion is not the model's


def test_an_unknown_plant_is_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["home", "--sim", "--plant", "rubber", "--logs", str(tmp_path)])
    assert rc == ExitCode.USAGE and "invalid choice: 'rubber'" in capsys.readouterr().err


def test_home_refuses_an_unknown_assembly_mode(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["home", "--sim", "--sim-start", "62", "62", "158", "--logs", str(tmp_path)])
    err = capsys.readouterr().err
    assert rc == int(ExitCode.UNREACHABLE), err
    assert "not reachable from home in the known assembly mode" in err and "Traceback" not in err
    run = load_run("last", tmp_path)
    assert run.meta["outcome"] == "refused" and run.meta["exit_code"] == int(ExitCode.UNREACHABLE)
    assert run.rows == 0


@pytest.mark.parametrize(("argv", "code", "text"), [
    (["--fault", "stall:9@1"], ExitCode.BAD_INPUT, "needs a joint 1, 2 or 3"),
    (["--fault", "wobble"], ExitCode.BAD_INPUT, "unknown kind"),
    (["--port", "/dev/null", "--fault", "unplug@1"], ExitCode.USAGE, "add --sim"),
    (["--port", "/nonexistent/ttyUSB9"], ExitCode.BUS_ERROR, "/nonexistent/ttyUSB9"),
])
def test_bad_options_are_refused_with_a_reason(plan_file: Path, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str],
                                               argv: list[str], code: ExitCode, text: str) -> None:
    rc = main(["execute", "--plan", str(plan_file), *argv, "--logs", str(tmp_path)])
    err = capsys.readouterr().err
    assert rc == int(code), err
    assert text in err and "Traceback" not in err


def test_bad_plan_files(tmp_path: Path, plan_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["execute", "--plan", str(tmp_path / "missing.json"), "--sim"])
    assert rc == int(ExitCode.PLAN_MISMATCH)
    broken = tmp_path / "broken.json"
    broken.write_text(plan_file.read_text()[:500])
    rc = main(["execute", "--plan", str(broken), "--sim"])
    assert rc == int(ExitCode.PLAN_MISMATCH)
    err = capsys.readouterr().err
    assert "broken.json" in err and "Traceback" not in err


def test_logs_list_and_show_with_plot(plan_file: Path, tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    main(["execute", "--plan", str(plan_file), "--sim", "--fault", "stall:3@0.5",
          "--logs", str(tmp_path), *AT_START])
    capsys.readouterr()
    assert main(["logs", "--json", "--logs", str(tmp_path)]) == 0
    runs = _json(capsys)["runs"]
    assert len(runs) == 1 and runs[0]["exit_code"] == int(ExitCode.STOP_TRACKING)
    png = tmp_path / "fig" / "run.png"
    assert main(["logs", "--logs", str(tmp_path), "show", runs[0]["run"], "--plot", str(png),
                 "--json"]) == 0
    d = _json(capsys)
    assert d["meta"]["outcome"] == "stopped" and d["events"]["stop"] == 1
    assert d["tracking_rms_deg"] > 0.0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    assert main(["logs", "show", "nope", "--logs", str(tmp_path)]) == int(ExitCode.BAD_INPUT)
