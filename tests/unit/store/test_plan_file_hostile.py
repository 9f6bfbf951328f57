"""Hostile plan files: binary, deep, huge, wrong types and shapes are refused with
PlanMismatchError (exit 9) naming the field — and, by a property test over mutated
plans, loading never ends in any other exception."""

from __future__ import annotations

import copy
import json
import math
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import spm_console.store.plan_file as plan_file
from spm_console.cli.main import main
from spm_console.cli.plan import _human
from spm_console.config.schema import Profile
from spm_console.core.planning.mvn import solve_mvn
from spm_console.core.servo.model import discretize, simulate
from spm_console.errors import ExitCode, PlanMismatchError, SpmError
from spm_console.store.plan_file import load_plan, plan_hash, plan_to_dict, save_plan
from tests.support.planning_cases import GOAL, START, polytope

Edit = Callable[[dict[str, Any]], Any]

@pytest.fixture(scope="module")
def valid(tmp_path_factory: pytest.TempPathFactory, agile: Profile) -> dict[str, Any]:
    """A valid plan document (MVN, N = 30)."""
    sv = agile.servo
    res = solve_mvn(discretize(sv.p, sv.ts_s, sv.discretization), START, GOAL, 30, polytope())
    path = tmp_path_factory.mktemp("plan") / "valid.json"
    save_plan(res.to_plan("mvn", plan_hash(agile)), path)
    return dict(json.loads(path.read_text()))

def _write(tmp: Path, doc: Any, name: str = "bad.json") -> Path:
    p = tmp / name
    p.write_text(json.dumps(doc))
    return p

def _set(path: tuple[Any, ...], value: Any) -> Edit:
    def edit(d: dict[str, Any]) -> None:
        node: Any = d
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] = value
    return edit

def _do(fn: Edit) -> Edit:
    """An edit in place (its return value is not a replacement document)."""
    def edit(d: dict[str, Any]) -> None:
        fn(d)
    return edit

# (edit of a valid plan — in place, or returning a replacement document — and words the
# message must contain)
FIELD_CASES: list[tuple[str, Edit, tuple[str, ...]]] = [
    ("extra is a list", _set(("extra",), [1, 2]), ("'extra' must be an object",)),
    ("qp_count is text", _set(("qp_count",), "abc"), ("'qp_count'", "integer")),
    ("qp_count is huge", _set(("qp_count",), 10**30), ("'qp_count'",)),
    ("qp_count is a bool", _set(("qp_count",), True), ("'qp_count'",)),
    ("cost is text", _set(("cost",), "abc"), ("'cost' must be a number",)),
    ("solve_seconds is a list", _set(("solve_seconds",), [1]), ("'solve_seconds'",)),
    ("Ts is NaN", _set(("Ts",), float("nan")), ("'Ts' must be a finite positive number",)),
    ("Ts is a bool", _set(("Ts",), True), ("'Ts' must be a number",)),
    ("Ts is negative", _set(("Ts",), -0.02), ("'Ts'",)),
    ("N is a float", _set(("N",), 30.0), ("N = 30.0",)),
    ("N is text", _set(("N",), "30"), ("N = '30'",)),
    ("version is true", _set(("version",), True), ("version",)),
    ("kind is a list", _set(("kind",), ["mvn"]), ("unknown plan kind",)),
    ("NaN in references", _set(("reference_deg", 5, 1), float("nan")),
     ("'reference_deg' row 5", "non-finite")),
    ("inf in positions", _set(("position_deg", 2, 0), float("inf")),
     ("'position_deg' row 2", "non-finite")),
    ("huge integer in velocities", _set(("velocity_degps", 3, 2), 10**400),
     ("'velocity_degps'", "too large")),
    ("1e308 in references (overflows the model)", _set(("reference_deg", 1, 0), 1e308),
     ("disagree with the servo model",)),
    ("text number in references", _set(("reference_deg", 3, 0), "100.0"),
     ("'reference_deg' row 3 must be 3 numbers",)),
    ("object in references", _set(("reference_deg", 4), {"a": 1}),
     ("'reference_deg' row 4 must be 3 numbers",)),
    ("ragged references", _set(("reference_deg", 7), [1.0, 2.0]),
     ("'reference_deg' row 7 must be 3 numbers",)),
    ("references not a list", _set(("reference_deg",), "abc"),
     ("'reference_deg' must be a list of rows",)),
    ("one sample only", lambda d: d.update(reference_deg=d["reference_deg"][:1]),
     ("'reference_deg' must have 2..100001 rows",)),
    ("model is a list", _set(("model",), [1]), ("'model' must be an object",)),
    ("model A is text", _set(("model", "A"), "abc"), ("model.A",)),
    ("model A is 3×3", _set(("model", "A"), [[1, 0, 0]] * 3), ("model.A",)),
    ("model B holds a bool", _set(("model", "B"), [True, 0.1]), ("model.B",)),
    ("model p is huge", _set(("model", "p"), 10**400), ("model: 'p'", "too large")),
    ("model p is negative", _set(("model", "p"), -3.0), ("model: 'p'",)),
    ("model discretization is a number", _set(("model", "discretization"), 3),
     ("model.discretization",)),
    ("region is text", _set(("region",), "abc"), ("region must be an object",)),
    ("region missing", _do(lambda d: d.pop("region")), ("missing key 'region'",)),
    ("region row is zero", _set(("region", "A", 0), [0, 0, 0]), ("region.A row 0 is zero",)),
    ("region b too short", _do(lambda d: d["region"]["b"].pop()), ("region.b must be a list of",)),
    ("region b holds null", _set(("region", "b", 2), None), ("region.b row 2",)),
    ("region too large", lambda d: d["region"].update(A=[[1, 0, 0]] * 1001, b=[200.0] * 1001),
     ("region.A must have 1..1000 rows",)),
    ("profile_hash is an object", _set(("profile_hash",), {"a": 1}), ("'profile_hash'",)),
    ("extra.check is a list", _set(("extra", "check"), [1]), ("'extra.check' must be an object",)),
    ("extra.check speed is text", _set(("extra", "check", "max_speed_samples_degps"), "x"),
     ("extra.check: 'max_speed_samples_degps' must be a number",)),
    ("extra.check.ok is text", _set(("extra", "check", "ok"), "yes"), ("'extra.check.ok'",)),
    ("extra.vmax_degps is text", _set(("extra", "vmax_degps"), "fast"), ("'vmax_degps'",)),
    ("n_minus_1_infeasible is a list", _set(("n_minus_1_infeasible",), [1]),
     ("n_minus_1_infeasible must be an object",)),
    ("certificate radius is text", _set(("n_minus_1_infeasible",),
                                        {"N": 29, "certificate": {"excluded_radius": "big"}}),
     ("'excluded_radius' must be a number",)),
    ("certificate for another N", _set(("n_minus_1_infeasible",), {"N": 12, "certificate": None}),
     ("n_minus_1_infeasible.N must be the plan's N − 1 = 29",)),
    ("certificate claims N − 1 feasible", _set(("n_minus_1_infeasible",),
                                               {"N": 29, "feasible": True, "certificate": None}),
     ("n_minus_1_infeasible.feasible must be false",)),
    ("certificate valid is text", _set(("n_minus_1_infeasible",),
                                       {"N": 29, "certificate": {"valid": "yes"}}),
     ("certificate: 'valid' must be true or false",)),
    ("search is text", _set(("n_minus_1_infeasible",), {"N": 29, "search": "abc"}),
     ("n_minus_1_infeasible.search must be a list",)),
    ("search step without a verdict", _set(("n_minus_1_infeasible",), {"N": 29, "search": [{"N": 3}]}),
     ("n_minus_1_infeasible.search[0] must be an object",)),
    ("extra.search_seconds is text", _do(lambda d: (
        d.update(n_minus_1_infeasible={"N": 29}), d["extra"].update(search_seconds="x"))),
     ("extra: 'search_seconds' must be a number",)),
    ("extra.check.points_per_interval is text", _set(("extra", "check", "points_per_interval"), "x"),
     ("extra.check: 'points_per_interval' must be an integer",)),
    ("extra.solver is a list", _set(("extra", "solver"), [1]), ("'extra.solver' must be an object",)),
    ("extra.start_deg is short", _set(("extra", "start_deg"), [1.0, 2.0]),
     ("extra.start_deg must be 3 numbers",)),
    ("extra.goal_deg missing", _do(lambda d: d["extra"].pop("goal_deg")),
     ("extra.goal_deg must be 3 numbers",)),
    ("extra.intersample is 0", _set(("extra", "intersample"), 0), ("'intersample'",)),
    ("extra.hold_first is text", _set(("extra", "hold_first"), "yes"), ("'hold_first'",)),
    ("extra.reference_limits_deg is a number", _set(("extra", "reference_limits_deg"), 3),
     ("'reference_limits_deg' must be [lower, upper]",)),
    ("extra.reference_limits_deg holds NaN", _set(("extra", "reference_limits_deg"),
                                                  [[0.0, float("nan"), 0.0], None]),
     ("reference_limits_deg[0] row 0 holds a non-finite value",)),
    ("model discretization is unknown", _set(("model", "discretization"), "euler"),
     ("model.discretization must be one of zoh, tustin",)),
    ("model Ts differs from Ts", _set(("model", "Ts"), 0.01), ("model.Ts = 0.01 s",)),
    ("root is a list", lambda d: [1, 2, 3], ("not a spm_console plan file",)),
    ("format is another", _set(("format",), "x"),
     ("not a spm_console plan file (format 'x', expected 'spm_console.plan')",)),
    ("format missing", _do(lambda d: d.pop("format")), ("(format key missing)",)),
]

@pytest.mark.parametrize(("name", "edit", "words"), FIELD_CASES, ids=[c[0] for c in FIELD_CASES])
def test_wrong_field_is_refused_naming_it(valid: dict[str, Any], agile: Profile, tmp_path: Path,
                                          name: str, edit: Edit, words: tuple[str, ...]) -> None:
    d = copy.deepcopy(valid)
    replaced = edit(d)
    path = _write(tmp_path, d if replaced is None else replaced)
    with pytest.raises(PlanMismatchError) as exc:
        load_plan(path, agile)
    assert exc.value.exit_code == ExitCode.PLAN_MISMATCH
    for w in words:
        assert w in exc.value.message, exc.value.message

def test_binary_deep_huge_and_unreadable_files(valid: dict[str, Any], agile: Profile,
                                               tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    cases: list[tuple[Path, str]] = []
    binary = tmp_path / "binary.json"
    binary.write_bytes(bytes(range(256)) * 4)
    cases.append((binary, "not UTF-8"))
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    cases.append((deep, "nested too deeply"))
    deep_obj = tmp_path / "deep_obj.json"
    deep_obj.write_text('{"a":' * 100_000 + "1" + "}" * 100_000)
    cases.append((deep_obj, "nested too deeply"))
    moderate = copy.deepcopy(valid)
    node = moderate["extra"]
    for _ in range(40):  # decodes fine, but deeper than the 32-level cap
        node["x"] = {}
        node = node["x"]
    cases.append((_write(tmp_path, moderate, "moderate.json"), "nested too deeply"))
    digits = tmp_path / "digits.json"
    digits.write_text('{"format": "spm_console.plan", "N": ' + "9" * 5000 + "}")
    cases.append((digits, "not valid JSON here: a number with more than "
                          f"{sys.get_int_max_str_digits()} digits$"))
    rows = copy.deepcopy(valid)
    rows["reference_deg"] = [[100.0, 100.0, 100.0]] * 100_002
    cases.append((_write(tmp_path, rows, "rows.json"), "'reference_deg' must have 2..100001 rows"))
    cases.append((tmp_path, "a directory, not a regular file"))
    cases.append((Path("/dev/zero"), "a device, not a regular file"))
    for path, words in cases:
        with pytest.raises(PlanMismatchError, match=words):
            load_plan(path, agile)
    monkeypatch.setattr(plan_file, "MAX_PLAN_BYTES", 1000)
    with pytest.raises(PlanMismatchError, match="larger than the 1000 bytes limit"):
        load_plan(_write(tmp_path, valid, "big.json"), agile)

def test_exact_certificate_shows(valid: dict[str, Any], tmp_path: Path,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    """An exact Farkas certificate (excluded radius ∞, stored as null) is shown, not a crash."""
    d = copy.deepcopy(valid)
    d["n_minus_1_infeasible"] = {"N": 29, "feasible": False, "certificate": {
        "excluded_radius": None, "residual_l1": 0.0, "valid": True}, "search": []}
    d["extra"]["check"]["region_violation_between_deg"] = None
    path = _write(tmp_path, d)
    # the fixture (MVN in 30 steps, no reference bounds) commands past a servo limit: shown,
    # then refused by the runtime's verification
    assert main(["plan", "show", str(path)]) == ExitCode.PLAN_REFUSED
    out, _ = capsys.readouterr()
    assert "excludes ‖x‖∞ < ∞" in out and "region violation nan deg" in out
    assert "runtime verification: REFUSED" in out and "outside the servo limits" in out

# --- property: mutated plans load or are refused, nothing else --------------------------------

JSON_LEAVES = (st.none() | st.booleans() | st.integers(min_value=-(10**30), max_value=10**30)
               | st.sampled_from([10**400, -(10**400), 0, 1, 2, 3, 30, 31])
               | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=8))
JSON_VALUES = st.recursive(JSON_LEAVES, lambda inner: st.lists(inner, max_size=4)
                           | st.dictionaries(st.text(max_size=6), inner, max_size=4), max_leaves=12)

def _paths(node: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every key path in a document (arrays: the first rows only, to keep the list short)."""
    out = [prefix] if prefix else []
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node[:3]):
            out += _paths(v, (*prefix, i))
    return out

MUTATION = st.tuples(st.sampled_from(["drop", "replace", "shape", "scale"]),
                     st.integers(min_value=0, max_value=10**6), JSON_VALUES,
                     st.sampled_from([float("nan"), float("inf"), 1e308, -1e308, 10**400, 0]))

_TMP = Path(tempfile.mkdtemp(prefix="spm-hostile-plans-"))

def _mutate(d: dict[str, Any], op: str, pick: int, value: Any, number: Any) -> None:
    paths = _paths(d)
    path = paths[pick % len(paths)]
    parent: Any = d
    for k in path[:-1]:
        parent = parent[k]
    key = path[-1]
    if op == "drop":
        if isinstance(parent, dict):
            del parent[key]
        else:
            parent.pop(key)
    elif op == "replace":
        parent[key] = value
    elif op == "shape":  # a longer or shorter array, or a row wrapped one level deeper
        v = parent[key]
        parent[key] = (v + v[:1]) if isinstance(v, list) and pick % 3 == 0 else \
            (v[:-1] if isinstance(v, list) and pick % 3 == 1 else [v])
    else:  # scale: a number replaced by NaN, inf, ±1e308, a huge integer or 0
        parent[key] = number

@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutations=st.lists(MUTATION, min_size=1, max_size=3))
def test_mutated_plans_load_or_are_refused(valid: dict[str, Any], agile: Profile,
                                           mutations: list[tuple[str, int, Any, Any]]) -> None:
    d = copy.deepcopy(valid)
    for op, pick, value, number in mutations:
        _mutate(d, op, pick, value, number)
    path = _TMP / "mutant.json"
    path.write_text(json.dumps(d, allow_nan=True))
    try:
        plan = load_plan(path, agile)
    except SpmError as exc:  # a clear refusal with its exit code
        assert exc.exit_code == ExitCode.PLAN_MISMATCH and exc.message
        return
    # accepted: a valid plan (its stored motion is the model's under its references) that
    # every reader can show
    assert plan.N >= 1 and np.all(np.isfinite(plan.reference_deg)) and math.isfinite(plan.Ts)
    model = discretize(agile.servo.p, agile.servo.ts_s, agile.servo.discretization)
    x0 = np.column_stack([plan.position_deg[0], plan.velocity_degps[0]])
    with np.errstate(all="ignore"):
        xs = simulate(model, x0, plan.reference_deg)
    assert np.abs(xs[..., 0] - plan.position_deg).max() <= 1e-6
    json.dumps(plan_to_dict(plan), allow_nan=False)
    assert _human(plan.summary(), None, "stored in the plan")
