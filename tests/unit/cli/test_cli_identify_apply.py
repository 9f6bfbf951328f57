"""``identify --experiment`` writes where the operator uses the model: beside the profile by
default (never over a file), into the profile itself with ``--apply`` (its [servo] only, the
profile kept as it was in a backup). The experiment is a recorded response of a known model
(the run on the wrist is tests/runtime's)."""

from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import spm_console.cli.identify as cli_identify
from spm_console.cli.main import main
from spm_console.config.load import load_profile
from spm_console.config.schema import Profile
from spm_console.core.servo.experiment import ExperimentFit, excitation, fit_record
from spm_console.core.servo.identify import response
from spm_console.core.servo.model import Dynamics
from spm_console.errors import ExitCode
from spm_console.motion.segments import ExecutionResult
from spm_console.services.identify.experiment import ExperimentRun
from tests.support.paths import ROOT

AGILE = ROOT / "profiles" / "agile_wrist.toml"
DYN = Dynamics(43.0, 0.79, 0.0035)


@pytest.fixture
def profile_file(tmp_path: Path) -> Path:
    d = tmp_path / "profiles"
    d.mkdir()
    p = d / "agile_wrist.toml"
    p.write_bytes(AGILE.read_bytes())
    return p


@pytest.fixture(scope="module")
def recorded(agile: Profile) -> tuple[ExperimentRun, ExperimentFit]:
    """The known model's response to the excitation about home, and its fit (without the
    load: the fit with it is the services' test)."""
    home = np.asarray(agile.home.theta_deg, float)
    ex = excitation(home, agile.servo.ts_s, 6.0, 120.0)
    t = np.arange(len(ex.reference_deg)) * agile.servo.ts_s
    meas = response(DYN, DYN.delay_s, t, ex.reference_deg, home)
    done = ExecutionResult("completed", ExitCode.OK, "completed", Path("logs") / "run")
    return ExperimentRun(None, done, ex, t, ex.reference_deg, meas), fit_record(
        ex, t, ex.reference_deg, meas)


@pytest.fixture
def experiments(monkeypatch: pytest.MonkeyPatch,
                recorded: tuple[ExperimentRun, ExperimentFit]) -> list[Profile]:
    """The experiment and its fit replaced by the recorded ones; the profiles it was asked
    to run with."""
    asked: list[Profile] = []

    def once(profile: Profile, req: Any) -> ExperimentRun:
        asked.append(profile)
        return recorded[0]

    monkeypatch.setattr(cli_identify, "experiment_once", once)
    monkeypatch.setattr(cli_identify, "fit_experiment", lambda profile, run: recorded[1])
    return asked


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, Any, str]:
    code = main(["identify", "--experiment", "--sim", "--json", *argv])
    out = capsys.readouterr()
    return code, json.loads(out.out) if out.out.strip() else None, out.err


def _without_servo(text: str) -> list[str]:
    """The profile's lines outside its [servo] tables."""
    keep, inside = [], False
    for line in text.splitlines():
        m = re.match(r"^\s*\[([^\]]+)\]", line)
        if m:
            inside = m.group(1).strip().split(".")[0] == "servo"
        if not inside and line.strip():
            keep.append(line)
    return keep


def test_apply_changes_the_profile_in_its_servo_only_and_keeps_a_backup(
        profile_file: Path, experiments: list[Profile], capsys: pytest.CaptureFixture[str]) -> None:
    before = profile_file.read_text(encoding="utf-8")
    code, d, err = _run(capsys, "--profile", str(profile_file), "--apply")
    assert code == 0, err
    backup = Path(d["backup"])
    assert d["profile_written"] == str(profile_file) and backup.parent == profile_file.parent
    assert backup.read_text(encoding="utf-8") == before  # kept as it was
    after = profile_file.read_text(encoding="utf-8")
    assert _without_servo(after) == _without_servo(before)  # every other line kept
    old, new = tomllib.loads(before), tomllib.loads(after)
    assert {k: v for k, v in old.items() if k != "servo"} == {
        k: v for k, v in new.items() if k != "servo"}
    servo = load_profile(profile_file).servo
    assert servo.identified is not None and servo.identified.source == str(
        Path(d["log_dir"]))
    assert servo.p == pytest.approx(DYN.wn, rel=1e-3) and servo.zeta == pytest.approx(
        DYN.zeta, rel=1e-3)
    # nothing else beside it: the profile and its backup
    assert sorted(p.name for p in profile_file.parent.iterdir()) == sorted(
        [profile_file.name, backup.name])


def test_by_default_the_identified_profile_is_written_beside_the_profile(
        profile_file: Path, experiments: list[Profile], capsys: pytest.CaptureFixture[str]) -> None:
    before = profile_file.read_bytes()
    written: list[Path] = []
    for _ in range(2):  # twice (within a second, or not): two files, none written over
        code, d, err = _run(capsys, "--profile", str(profile_file))
        assert code == 0, err
        written.append(Path(d["profile_written"]))
    assert written[0] != written[1] and profile_file.read_bytes() == before
    for w in written:
        assert w.parent == profile_file.parent
        assert re.match(r"^agile_wrist\.identified-[0-9T-]+Z(-\d+)?\.toml$", w.name), w.name
        assert load_profile(w).servo.identified is not None


def test_apply_and_out_together_are_refused_before_anything_moves(
        profile_file: Path, experiments: list[Profile], capsys: pytest.CaptureFixture[str],
        tmp_path: Path) -> None:
    code, _, err = _run(capsys, "--profile", str(profile_file), "--apply", "--out",
                        str(tmp_path / "new.toml"))
    assert code == int(ExitCode.BAD_INPUT) and "--apply" in err and "--out" in err
    code, _, err = _run(capsys, "--profile", str(profile_file), "--out", str(profile_file))
    assert code == int(ExitCode.BAD_INPUT) and "--apply" in err
    assert experiments == []
    code = main(["identify", "--csv", str(tmp_path / "x.csv"), "--apply"])
    assert code == int(ExitCode.BAD_INPUT) and "--experiment" in capsys.readouterr().err
