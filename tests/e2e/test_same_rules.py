"""One operator runtime, one set of rules, whichever front end starts the motion.

The CLI (``execute``), a script and the console (Pilot) each run the same plan, whose start
is 1.5° from home, on the emulated bus:

* homed first: every front end homes (or is refused) before it executes;
* the approach tolerance is the profile's ``safety.approach_tolerance_deg``: with 2° the wrist
  at home starts the plan at once, with the default 0.5° it moves to the start first;
* one run-log metadata schema.

(SIGTERM → E-stop through each front end: ``test_signals.py``, ``test_script.py``,
``tui/test_signals.py``.)
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.config.load import load_profile
from spm_console.config.schema import Profile
from spm_console.errors import ExitCode
from spm_console.motion.logs.runlog import list_runs, load_run
from spm_console.motion.plans import synthetic_plan
from spm_console.store.plan_file import save_plan
from tests.support.paths import ROOT as PROJECT_ROOT

ROOT = PROJECT_ROOT
START = np.array([136.5, 135.0, 135.0])
GOAL = np.array([125.0, 130.0, 128.0])


def _profile(tmp: Path, tolerance_deg: float | None) -> Path:
    """The default profile, with another approach tolerance when given."""
    text = (ROOT / "profiles" / "agile_wrist.toml").read_text()
    if tolerance_deg is not None:
        assert "[safety]\n" in text
        text = text.replace("[safety]\n", f"[safety]\napproach_tolerance_deg = {tolerance_deg}\n", 1)
    path = tmp / f"tol_{tolerance_deg}.toml"
    path.write_text(text)
    return path


def _phases(log_dir: str | Path) -> list[str]:
    return [p["phase"] for p in load_run(log_dir).meta["plans"]]


def _cli(profile: Path, plan: Path, logs: Path, capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    code = main(["execute", "--profile", str(profile), "--plan", str(plan), "--sim", "--json",
                 "--logs", str(logs)])
    d: dict[str, Any] = json.loads(capsys.readouterr().out)
    assert code == 0, d
    return d


def _script(profile: Path, logs: Path, capsys: pytest.CaptureFixture[str],
            home: bool = True) -> tuple[int, dict[str, Any]]:
    text = f"""
[session]
profile = "{profile}"

{'[[step]]' + chr(10) + 'do = "home"' if home else ''}

[[step]]
do = "workspace"

[[step]]
do = "plan"
start = {{theta = {START.tolist()}}}
goal = {{theta = {GOAL.tolist()}}}
steps = 40

[[step]]
do = "execute"
"""
    f = logs.parent / f"s_{logs.name}.toml"
    f.write_text(text)
    code = main(["script", str(f), "--logs", str(logs)])
    return code, json.loads(capsys.readouterr().out)


@pytest.mark.parametrize(("tolerance", "phases"), [(2.0, ["plan"]), (None, ["approach", "plan"])],
                         ids=["tolerance 2 deg", "default 0.5 deg"])
def test_approach_tolerance_and_homing_are_the_profiles_for_cli_and_script(
        tmp_path: Path, agile: Profile, capsys: pytest.CaptureFixture[str],
        tolerance: float | None, phases: list[str]) -> None:
    profile = _profile(tmp_path, tolerance)
    plan = tmp_path / "plan.json"
    save_plan(synthetic_plan(load_profile(profile), START, GOAL, 1.0), plan)
    d = _cli(profile, plan, tmp_path / "cli", capsys)
    assert d["homing"]["outcome"] == "completed"  # homed first
    assert _phases(d["log_dir"]) == phases
    code, summary = _script(profile, tmp_path / "script", capsys)
    assert code == 0, summary
    ex = summary["steps"][-1]["result"]
    assert _phases(ex["log_dir"]) == phases
    # one metadata schema
    cli_meta = load_run(d["log_dir"]).meta
    script_meta = load_run(ex["log_dir"]).meta
    assert set(cli_meta) == set(script_meta)
    assert cli_meta["homing"] == script_meta["homing"] == "done"
    assert [r.meta["kind"] for r in list_runs(tmp_path / "script")] == ["home", "execute"]


def test_a_script_that_does_not_home_is_refused(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    code, summary = _script(ROOT / "profiles" / "agile_wrist.toml", tmp_path / "logs", capsys,
                            home=False)
    assert code == int(ExitCode.BAD_INPUT)
    assert "not homed" in summary["message"]
    assert not (tmp_path / "logs").exists() or not any(
        r.meta["kind"] == "execute" and load_run(r.path).rows for r in list_runs(tmp_path / "logs"))
