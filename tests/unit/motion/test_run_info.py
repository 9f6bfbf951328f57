"""The typed run summary of a log: outcome, exit code, stop kind, duration, plan; tolerant
of malformed meta.json; the stop wording and exit codes agree with the executor's."""

from __future__ import annotations

import json
import typing
from pathlib import Path

import pytest

from spm_console.errors import ExitCode
from spm_console.motion.logs.run_info import STOP_KIND_BY_EXIT, STOP_LABELS, run_info
from spm_console.motion.logs.runlog import list_runs, load_run
from spm_console.motion.safety import EXIT_CODES, StopKind
from tests.support.runlog_helpers import GOAL, START, write_run


def test_stop_kinds_and_exit_codes_agree_with_the_executor() -> None:
    assert set(STOP_LABELS) == set(typing.get_args(StopKind)) == set(EXIT_CODES)
    assert {int(code): kind for kind, code in EXIT_CODES.items()} == STOP_KIND_BY_EXIT
    assert len(set(STOP_LABELS.values())) == len(STOP_LABELS)  # every reason reads differently


def test_a_stopped_run_says_why_with_its_exit_code(tmp_path: Path) -> None:
    estop = write_run(tmp_path, "stopped", 20, "E-stop: operator E-stop (SPACE)", "estop")
    comm = write_run(tmp_path, "stopped", 22, "communication lost: 3 cycles", "comm")
    done = write_run(tmp_path, "completed", 0, "executed 20 cycles (0.40 s)")
    by_name = {r.name: r.info for r in list_runs(tmp_path)}
    a, b, c = by_name[estop.path.name], by_name[comm.path.name], by_name[done.path.name]
    assert (a.outcome, a.exit_code, a.stop_kind, a.stop_label) == ("stopped", 20, "estop", "E-stop")
    assert (b.outcome, b.exit_code, b.stop_label) == ("stopped", 22, "communication lost")
    assert (c.outcome, c.exit_code, c.stop_kind, c.stop_label) == ("completed", 0, None, "")
    assert a.message == "E-stop: operator E-stop (SPACE)"
    assert a.loop_s == pytest.approx(0.4) and a.samples == 20
    assert a.duration_s is not None and a.duration_s >= 0
    assert a.plan is not None and a.plan.kind == "mvn" and a.plan.after_approach
    assert a.plan.first_reference_deg == START and a.plan.last_reference_deg == GOAL
    assert a.kind == "execute" and a.name == estop.path.name


def test_the_stop_kind_from_events_or_the_exit_code(tmp_path: Path) -> None:
    log = write_run(tmp_path, "stopped", 21, "tracking error", "tracking")
    meta = json.loads((log.path / "meta.json").read_text())
    del meta["stats"]["stop"]
    (log.path / "meta.json").write_text(json.dumps(meta))
    run = load_run(log.path)
    assert run.info.stop_kind == "tracking"  # from the stop event
    meta["exit_code"] = int(ExitCode.STOP_LIMIT)
    assert run_info("x", meta).stop_kind == "limit"  # no events: from the exit code
    assert run_info("x", {**meta, "outcome": "completed"}).stop_kind is None


def test_killed_and_running_runs(tmp_path: Path) -> None:
    killed = write_run(tmp_path, "killed")
    [info] = [r.info for r in list_runs(tmp_path)]
    assert info.name == killed.path.name
    assert info.outcome == "killed" and info.exit_code is None and info.duration_s is None
    assert "ended without closing its log" in info.message


def test_a_run_log_from_before_the_rename_reads_its_references() -> None:
    """Run logs before 0.2.0 named θ*(0) and θ*(N) ``start_deg`` and ``goal_deg``."""
    old = {"outcome": "completed", "plans": [{"kind": "mvn", "phase": "plan",
                                              "start_deg": [1.0, 2.0, 3.0],
                                              "goal_deg": [4.0, 5.0, 6.0]}]}
    plan = run_info("folder", old).plan
    assert plan is not None
    assert plan.first_reference_deg == (1.0, 2.0, 3.0)
    assert plan.last_reference_deg == (4.0, 5.0, 6.0)


@pytest.mark.parametrize("meta", [
    {},
    {"outcome": 3, "exit_code": "20", "plans": "mvn", "stats": [], "start_time": "yesterday"},
    {"outcome": "stopped", "exit_code": 20.5, "plans": [{"kind": 1, "start_deg": [1, 2]}],
     "stats": {"stop": "estop", "duration_s": float("nan")}, "end_time": 5},
    {"outcome": "completed", "plans": [None, {"first_reference_deg": ["a", 1, 2],
                                              "last_reference_deg": None}],
     "samples": True, "start_time": "2026-01-01T00:00:00", "end_time": "2026-01-01T00:00:02"},
])
def test_malformed_meta_reads_as_unknown_never_raises(meta: dict[str, object]) -> None:
    info = run_info("folder", meta)
    assert info.name == "folder"
    assert info.exit_code is None and info.loop_s is None and info.samples is None
    assert info.plan is None or (info.plan.first_reference_deg is None
                                 and info.plan.last_reference_deg is None)
    if meta.get("start_time") == "2026-01-01T00:00:00":
        assert info.duration_s == pytest.approx(2.0)
    else:
        assert info.duration_s is None


@pytest.mark.parametrize(("outcome", "stop", "reason"), [
    ("completed", None, ""),
    ("refused", None, "execute refused: the wrist is not homed"),
    ("error", None, "execute refused: the wrist is not homed"),
    ("stopped", "estop", "E-stop"),
])
def test_the_reason_of_a_run(outcome: str, stop: str | None, reason: str) -> None:
    meta = {"outcome": outcome, "exit_code": 5,
            "message": "execute refused: the wrist is not homed",
            "stats": {"stop": {"kind": stop}} if stop else {}}
    assert run_info("r", meta).reason == reason
