"""``spm-console emulate --as-built FILE.toml [--jig] [--truth-log FILE.csv]``: the physical
wrist as built, its JSON head and summary; the option conflicts are usage errors."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from spm_console.cli.main import main
from spm_console.errors import ExitCode
from tests.support.paths import ROOT

pytestmark = pytest.mark.realtime  # an emulated bus on the wall clock (see tests/conftest.py)

TWIN = ROOT / "tests" / "data" / "as_built" / "twin.toml"


@pytest.mark.parametrize("args", [
    ["--plant", "ideal", "--as-built", str(TWIN)],
    ["--plant", "ideal", "--jig"],
    ["--plant", "ideal", "--truth-log", "t.csv"],
    ["--as-built", str(TWIN)],  # the profile's [plant] model: ideal
    ["--plant", "physical", "--jig", "--initial", "130", "130", "130"],
])
def test_options_that_need_the_physical_wrist_are_usage_errors(
        args: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["emulate", *args, "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == ExitCode.USAGE == out["exit_code"] and not out["ok"]
    assert "--" in out["error"]


def test_a_broken_as_built_file_is_bad_input_naming_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[as_built]\nbase_tilt_deg = [0, 11]\n")
    rc = main(["emulate", "--plant", "physical", "--as-built", str(bad), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == ExitCode.BAD_INPUT == out["exit_code"]
    assert str(bad) in out["error"] and "as_built.base_tilt_deg[1]" in out["error"]
    rc = main(["emulate", "--plant", "physical", "--truth-log", str(tmp_path / "t.txt"), "--json"])
    assert rc == ExitCode.BAD_INPUT and ".csv" in json.loads(capsys.readouterr().out)["error"]


def test_emulate_serves_the_wrist_as_built_and_logs_its_truth(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = tmp_path / "truth.csv"
    rc = main(["emulate", "--plant", "physical", "--as-built", str(TWIN), "--jig",
               "--truth-log", str(log), "--link", "socket", "--duration", "1", "--json"])
    head, summary = (json.loads(line) for line in capsys.readouterr().out.splitlines())
    assert rc == 0
    assert head["port"].startswith("unix:") and head["as_built"] is True and head["jig"] is True
    assert head["ids"] == [3, 1, 2] and head["truth_log"] == str(log)
    assert summary["stopped"] and summary["truth_log"]["path"] == str(log)
    rows = summary["truth_log"]["rows"]
    assert 90 <= rows <= 130 and not summary["truth_log"]["full"]
    with open(log, newline="") as f:
        assert len(list(csv.reader(f))) == rows + 1  # closed, flushed, with its header
