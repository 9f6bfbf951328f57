"""Inputs a hostile-user probe found mishandled: each now refused with its code and reason."""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.core.workspace.certify import CertifiedSet
from spm_console.errors import ExitCode

START = ["127.53", "83.23", "85.25"]
GOAL = ["66.80", "155.00", "131.48"]


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_json_failures_print_one_object(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _run(capsys, "fk", "--json", "--theta", "nan", "110", "105")
    assert code == ExitCode.BAD_INPUT and "finite" in err
    assert json.loads(out) == {"ok": False, "exit_code": 4, "error": json.loads(out)["error"]}
    code, out, _ = _run(capsys, "fk", "--json", "--theta", "1", "2")  # usage error
    assert code == ExitCode.USAGE and json.loads(out)["exit_code"] == 2


def test_a_deeply_nested_profile_is_a_profile_error(tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "deep.toml"
    bad.write_text(Path("profiles/agile_wrist.toml").read_text()
                   + "\n[x]\ny = " + "[" * 100_000 + "]" * 100_000 + "\n")
    code, _, err = _run(capsys, "fk", "--theta", "95", "110", "105", "--profile", str(bad))
    assert code == ExitCode.PROFILE_ERROR and "nested too deeply" in err


def test_a_log_folder_that_cannot_exist_is_bad_input(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    plan = tmp_path / "p.json"
    assert _run(capsys, "plan", "mvn", "--start", *START, "--goal", *GOAL, "--out", str(plan))[0] == 0
    code, _, err = _run(capsys, "execute", "--sim", "--plan", str(plan), "--logs", "/proc/x")
    assert code == ExitCode.BAD_INPUT and "/proc/x" in err
    code, _, err = _run(capsys, "logs", "--logs", str(plan))  # a file, not a folder
    assert code == ExitCode.BAD_INPUT and "not a folder" in err


def test_plan_out_never_replaces_a_device(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    code, _, err = _run(capsys, "plan", "mvn", "--start", *START, "--goal", *GOAL, "--out", str(fifo))
    assert code == ExitCode.BAD_INPUT and "not a regular file" in err
    assert stat.S_ISFIFO(fifo.stat().st_mode)


def test_plan_show_says_what_the_runtime_decides(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    plan = tmp_path / "p.json"
    assert _run(capsys, "plan", "mvn", "--start", *START, "--goal", *GOAL, "--out", str(plan))[0] == 0
    code, out, _ = _run(capsys, "plan", "show", str(plan), "--json")
    assert code == 0 and json.loads(out)["verified"] is True
    from spm_console.motion.plans import plan_from_references
    from spm_console.store.plan_file import load_plan, save_plan
    from tests.support.ws_helpers import agile_profile

    prof = agile_profile()
    ref = load_plan(plan, prof).reference_deg  # the same references, three times faster
    save_plan(plan_from_references(prof, ref[::3], "synthetic"), plan)
    code, out, _ = _run(capsys, "plan", "show", str(plan))
    assert code == ExitCode.PLAN_REFUSED and "REFUSED" in out


def test_a_cache_folder_that_is_a_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "file"
    f.write_text("x")
    code, _, err = _run(capsys, "workspace", "check", "--theta", "100", "100", "100",
                        "--cache-dir", str(f))
    assert code == ExitCode.CACHE_ERROR and "not a folder" in err


def test_round_off_past_the_grid_edge_is_on_it() -> None:
    cs = CertifiedSet(np.ones((3, 3, 3), bool), np.zeros(3), 1.0)
    assert cs.contains(np.array([2.0 + 1e-10, 1.0, 1.0]))
    assert not cs.contains(np.array([2.0 + 1e-6, 1.0, 1.0]))


@pytest.mark.parametrize("argv", [
    ["fk", "--json", "--theta", "1", "2"],
    ["fk", "--json"],
    ["ik", "--json", "--rpy", "x", "0", "0"],
    ["workspace", "--json"],
    ["workspace", "check", "--json", "--bogus"],
    ["plan", "mvn", "--json", "--steps", "x"],
    ["servo", "ping", "--json", "--nope"],
    ["execute", "--json", "--plan"],
    ["follow", "--json", "--deadman", "soon"],
    ["logs", "--json", "--nope"],
    ["script", "--json"],
    ["bogus", "--json"],
])
def test_usage_errors_with_json_give_their_reason_in_one_object(
        capsys: pytest.CaptureFixture[str], argv: list[str]) -> None:
    """argparse's reason is on stderr (after the usage line) and in the one JSON object on
    stdout (it said "usage error (see stderr)")."""
    code, out, err = _run(capsys, *argv)
    assert code == ExitCode.USAGE
    [line] = out.splitlines()
    obj = json.loads(line)
    assert set(obj) == {"ok", "exit_code", "error"} and obj["ok"] is False
    assert obj["exit_code"] == 2
    reason = obj["error"].split(": ", 1)[1]  # after "spm-console CMD: "
    assert f"error: {reason}" in err and "see stderr" not in obj["error"]
