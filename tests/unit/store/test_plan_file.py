"""Plan files: round trip, and refusal of mismatched or corrupt files (PlanMismatchError)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from spm_console.config.schema import Profile
from spm_console.core.planning.mintime import solve_mintime
from spm_console.core.planning.mvn import solve_mvn
from spm_console.core.servo.model import discretize
from spm_console.errors import ExitCode, PlanMismatchError
from spm_console.motion.plans import synthetic_plan
from spm_console.store.plan_file import load_plan, plan_hash, plan_to_dict, save_plan
from tests.support.planning_cases import GOAL, START, polytope

SPEC_KEYS = ("kind", "Ts", "N", "reference_deg", "position_deg", "velocity_degps", "cost",
             "solve_seconds", "qp_count", "region", "model")


@pytest.fixture(scope="module")
def plan_path(tmp_path_factory: pytest.TempPathFactory, agile: Profile) -> Path:
    sv = agile.servo
    res = solve_mvn(discretize(sv.p, sv.ts_s, sv.discretization), START, GOAL, 60, polytope())
    path = tmp_path_factory.mktemp("plans") / "mvn.json"
    save_plan(res.to_plan("mvn", plan_hash(agile)), path)
    return path


def _edit(src: Path, dst: Path, fn: Any) -> Path:
    d = json.loads(src.read_text())
    fn(d)
    dst.write_text(json.dumps(d))
    return dst


def test_round_trip_and_spec_keys(plan_path: Path, agile: Profile) -> None:
    d = json.loads(plan_path.read_text())
    for key in SPEC_KEYS:
        assert key in d
    assert set(d["model"]) >= {"A", "B", "p", "discretization"}
    assert set(d["region"]) == {"A", "b"}
    assert np.asarray(d["reference_deg"]).shape == (61, 3)
    plan = load_plan(plan_path, agile)
    assert plan.N == 60 and plan.kind == "mvn" and plan.Ts == 0.02
    assert plan.reference_deg[-1] == pytest.approx(GOAL)
    assert plan.check is not None and plan.check.ok is True
    assert plan.region.halfspaces == polytope().halfspaces


def test_typed_fields_keep_the_document(plan_path: Path, agile: Profile, tmp_path: Path) -> None:
    """The typed fields are read from, and written back to, the same JSON keys as before."""
    d = json.loads(plan_path.read_text())
    plan = load_plan(plan_path, agile)
    assert plan.model.p == agile.servo.p and plan.model.method == agile.servo.discretization
    assert plan.model.ts == plan.Ts == d["model"]["Ts"]
    opts = plan.options
    assert opts is not None and opts.start_deg == pytest.approx(START)
    assert opts.goal_deg == pytest.approx(GOAL) and opts.vmax_degps is None
    assert opts.intersample == 1 and opts.hold_first and opts.reference_limits_deg is None
    assert plan.check is not None and plan.check.points_per_interval == d["extra"]["check"][
        "points_per_interval"]
    assert plan.certificate is None and plan.solver == d["extra"]["solver"] and plan.notes == {}
    assert json.loads(json.dumps(plan_to_dict(plan))) == d
    # minimum time: the N − 1 record at the top level, the search time under "extra"
    sv = agile.servo
    res = solve_mintime(discretize(sv.p, sv.ts_s, sv.discretization), START, GOAL, polytope(), 45.0)
    save_plan(res.to_plan("mintime", plan_hash(agile)), tmp_path / "mt.json")
    d = json.loads((tmp_path / "mt.json").read_text())
    assert set(d["n_minus_1_infeasible"]) == {"N", "feasible", "certificate", "search"}
    assert d["n_minus_1_infeasible"]["N"] == res.N - 1 and "search_seconds" in d["extra"]
    mt = load_plan(tmp_path / "mt.json", agile)
    assert mt.certificate == res.record() and mt.options is not None
    assert mt.options.vmax_degps == 45.0
    assert json.loads(json.dumps(plan_to_dict(mt))) == d
    # a synthetic plan: free-form notes under "extra", no planner options or report
    save_plan(synthetic_plan(agile, START, GOAL, 0.5), tmp_path / "syn.json")
    d = json.loads((tmp_path / "syn.json").read_text())
    assert d["extra"] == {"duration_s": 0.5} and "n_minus_1_infeasible" not in d
    syn = load_plan(tmp_path / "syn.json", agile)
    assert syn.notes == {"duration_s": 0.5} and syn.options is None and syn.check is None
    assert json.loads(json.dumps(plan_to_dict(syn))) == d


def test_other_profile_is_refused(plan_path: Path, agile: Profile, coaxial: Profile) -> None:
    with pytest.raises(PlanMismatchError, match="another profile") as exc:
        load_plan(plan_path, coaxial)
    assert exc.value.exit_code == ExitCode.PLAN_MISMATCH
    changed = agile.model_copy(update={"servo": agile.servo.model_copy(update={"p": 30.0})})
    with pytest.raises(PlanMismatchError, match="another profile"):
        load_plan(plan_path, changed)
    # a change that does not shape plans (safety thresholds) keeps them valid
    safer = agile.model_copy(update={"safety": agile.safety.model_copy(
        update={"tracking_error_deg": 1.0})})
    assert load_plan(plan_path, safer).N == 60


@pytest.mark.parametrize(("edit", "message"), [
    (lambda d: d.update(Ts=0.01), "Ts"),
    (lambda d: d["model"].update(p=30.0), "servo model"),
    (lambda d: d["model"].update(A=[[1, 0], [0, 1]]), "matrices"),
    (lambda d: d["reference_deg"][20].__setitem__(1, d["reference_deg"][20][1] + 0.5), "disagree"),
    (lambda d: d["position_deg"][30].__setitem__(0, 0.0), "disagree"),
    (lambda d: d.update(N=59), "N = 59"),
    (lambda d: d.pop("velocity_degps"), "missing key 'velocity_degps'"),
    (lambda d: d.update(reference_deg=[[1, 2]] * 61), "3 columns"),
    (lambda d: d.update(kind="teleport"), "unknown plan kind"),
    (lambda d: d.update(version=99), "version"),
    (lambda d: d.update(format="other"), "not a spm_console plan"),
    (lambda d: d["region"].update(b=[1.0]), "region"),
])
def test_mismatched_or_edited_files_are_refused(plan_path: Path, agile: Profile, tmp_path: Path,
                                                edit: Any, message: str) -> None:
    bad = _edit(plan_path, tmp_path / "bad.json", edit)
    with pytest.raises(PlanMismatchError, match=message):
        load_plan(bad, agile)


def test_corrupt_and_missing_files(plan_path: Path, agile: Profile, tmp_path: Path) -> None:
    trunc = tmp_path / "trunc.json"
    trunc.write_text(plan_path.read_text()[:500])
    with pytest.raises(PlanMismatchError, match="not valid JSON"):
        load_plan(trunc, agile)
    with pytest.raises(PlanMismatchError, match="cannot read"):
        load_plan(tmp_path / "nope.json", agile)
    nan = _edit(plan_path, tmp_path / "nan.json", lambda d: d["velocity_degps"][3].__setitem__(0, None))
    with pytest.raises(PlanMismatchError):
        load_plan(nan, agile)
