"""plan mvn | mintime | show and identify as an API: JSON keys, files, exit codes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.polytope.region import Region
from spm_console.core.servo.identify import response
from spm_console.core.servo.model import discretize
from spm_console.errors import ExitCode
from spm_console.store.plan_schema import plan_from_dict
from tests.support.planning_cases import polytope
from tests.support.reference_qp import solve_reference

START = ["127.53", "83.23", "85.25"]
GOAL = ["66.80", "155.00", "131.48"]


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def region_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    p = tmp_path_factory.mktemp("region") / "region.json"
    p.write_text(json.dumps({"region": polytope().to_dict(), "halfspaces": 61}))
    return p


def test_mvn_writes_a_plan_that_show_accepts(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                             region_file: Path) -> None:
    out = tmp_path / "mvn.json"
    png = tmp_path / "mvn.png"
    code, so, _ = run(capsys, "plan", "mvn", "--start", *START, "--goal", *GOAL, "--steps", "150",
                      "--region", str(region_file), "--out", str(out), "--plot", str(png), "--json")
    assert code == 0
    rec = json.loads(so)
    assert rec["kind"] == "mvn" and rec["N"] == 150 and rec["check"]["ok"]
    assert rec["region_kind"] == "given" and rec["region"].startswith("the region of file")
    assert rec["halfspaces"] == 61 and "61 half-spaces" in rec["region"]
    assert png.stat().st_size > 10_000
    code, so, _ = run(capsys, "plan", "show", str(out), "--json")
    assert code == 0
    d = json.loads(so)
    assert np.asarray(d["position_deg"]).shape == (151, 3)
    assert d["cost"] == pytest.approx(rec["cost"])
    code, so, _ = run(capsys, "plan", "show", str(out))
    assert code == 0 and "mvn: N = 150" in so and "between samples" in so


def test_mintime_records_the_certificate(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    box = tmp_path / "box.json"
    box.write_text(json.dumps(Region.box(65.0, 155.0).to_dict()))
    out = tmp_path / "mt.json"
    code, so, _ = run(capsys, "plan", "mintime", "--start", *START, "--goal", *GOAL,
                      "--vmax", "50", "--region", str(box), "--out", str(out), "--json")
    assert code == 0
    rec = json.loads(so)
    assert rec["kind"] == "mintime" and rec["N"] == 72
    cert = rec["n_minus_1_infeasible"]
    assert cert["N"] == 71 and cert["certificate"]["valid"]
    assert json.loads(out.read_text())["n_minus_1_infeasible"]["N"] == 71


def test_a_region_file_cannot_take_a_plan_outside_the_workspace(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    # two feasible grid nodes in the 65..155° box: the motion leaves the first toward a
    # singular fine node 0.5° away (within Δ of an infeasible grid node), which the
    # workspace does not certify even refined -> refused (exit 26), no file
    box = tmp_path / "box.json"
    box.write_text(json.dumps(Region.box(65.0, 155.0).to_dict()))
    out = tmp_path / "mt.json"
    code, _, err = run(capsys, "plan", "mintime", "--start", "155", "107", "71", "--goal", "137",
                       "77", "89", "--vmax", "50", "--region", str(box), "--out", str(out))
    assert code == ExitCode.PLAN_REFUSED
    assert "does not certify" in err and not out.exists()


def test_errors_have_distinct_exit_codes(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                         region_file: Path) -> None:
    code, _, err = run(capsys, "plan", "mvn", "--start", *START, "--goal", *GOAL, "--steps", "40",
                       "--vmax", "50", "--region", str(region_file))
    assert code == ExitCode.INFEASIBLE and "N = 40" in err
    small = tmp_path / "small.json"
    small.write_text(json.dumps(Region.box(90.0, 150.0).to_dict()))
    code, _, err = run(capsys, "plan", "mvn", "--start", *START, "--goal", *GOAL,
                       "--region", str(small))
    assert code == ExitCode.INFEASIBLE and "outside the region P" in err
    code, _, err = run(capsys, "plan", "mvn", "--start", "10", "83", "85", "--goal", *GOAL,
                       "--region", str(region_file))
    assert code == ExitCode.BAD_INPUT and "servo limits" in err
    code, _, err = run(capsys, "plan", "mvn", "--start", *START, "--goal", *GOAL,
                       "--steps", "1", "--region", str(region_file))
    assert code == ExitCode.BAD_INPUT
    junk = tmp_path / "junk.json"
    junk.write_text("{not json")
    code, _, err = run(capsys, "plan", "mvn", "--start", *START, "--goal", *GOAL,
                       "--region", str(junk))
    assert code == ExitCode.BAD_INPUT and "not valid JSON" in err
    code, _, err = run(capsys, "plan", "show", str(junk))
    assert code == ExitCode.PLAN_MISMATCH and "not valid JSON" in err
    code, _, err = run(capsys, "plan", "show", str(tmp_path / "missing.json"))
    assert code == ExitCode.PLAN_MISMATCH


def test_identify_from_csv(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    t = np.arange(60) * 0.02
    ref = np.tile([100.0, 120.0, 90.0], (60, 1))
    ref[5:] = [130.0, 100.0, 95.0]
    tick = 360.0 / 4096
    meas = np.round(response(30.0, 0.0, t, ref, ref[0]) / tick) * tick
    f = tmp_path / "step.csv"
    rows = ["t,ref1,ref2,ref3,meas1,meas2,meas3"]
    rows += [",".join(f"{v:.6f}" for v in (t[k], *ref[k], *meas[k])) for k in range(60)]
    f.write_text("\n".join(rows) + "\n")
    code, so, _ = run(capsys, "identify", "--csv", str(f), "--json")
    assert code == 0
    d = json.loads(so)
    assert abs(d["p"] / 30.0 - 1) < 0.02 and d["joints"] == 3
    bad = tmp_path / "bad.csv"
    bad.write_text("t,x\n0,1\n")
    code, _, err = run(capsys, "identify", "--csv", str(bad))
    assert code == ExitCode.BAD_INPUT and "ref1" in err


@pytest.fixture(scope="module")
def cache_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("wscache")


def test_paper_experiments_with_the_real_workspace(capsys: pytest.CaptureFixture[str],
                                                    cache_dir: Path, tmp_path: Path) -> None:
    """MVN: the goal is outside the cached P, so the plan follows a route through the
    workspace's region cover and is optimal for that route (cvxpy + Clarabel agree).
    Minimum time: the paper's pair plans on the 2° grid through the cover too, at the lower
    bound N* = 65 (joint 2 travels 65° at 50°/s); the single-region planner's refined region
    gets the same N* (tests/unit/motion/test_refined_certified_set.py)."""
    out = tmp_path / "mvn.json"
    code, so, err = run(capsys, "plan", "mvn", "--start", *START, "--goal", *GOAL,
                        "--cache-dir", str(cache_dir), "--out", str(out), "--json")
    assert code == 0, err
    rec = json.loads(so)
    assert rec["region_kind"] == "route" and rec["check"]["ok"]
    assert rec["region"].startswith("a route through the workspace's region cover: 2 regions (P → ")
    plan = plan_from_dict(json.loads(out.read_text()))
    assert plan.route is not None and list(plan.route.switch) == rec["route"]["switch_samples"]
    pb = PlanProblem(discretize(32.22, 0.02), np.array(START, float), np.array(GOAL, float), 150,
                     plan.region, ref_lo_deg=np.full(3, 60.0), ref_hi_deg=np.full(3, 160.0),
                     route=plan.route)
    ref = solve_reference(pb)
    assert abs(rec["cost"] - ref.cost) <= 1e-4 * ref.cost
    code, so, err = run(capsys, "plan", "mintime", "--start", "70", "90", "80", "--goal", *GOAL,
                        "--vmax", "50", "--cache-dir", str(cache_dir), "--json")
    assert code == 0, err
    rec = json.loads(so)
    assert rec["region_kind"] == "route" and rec["check"]["ok"] and rec["N"] == 65
    assert "for this sequence of 2 regions" in json.dumps(rec["n_minus_1_infeasible"])
