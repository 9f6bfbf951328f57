"""A plan file the runtime refuses powers nothing: ``execute`` has the motion process verify it
against this profile's workspace and rules before homing, so no run starts, no servo gets
torque, and the refusal (exit 26) says that nothing moved."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.errors import ExitCode
from spm_console.motion.plans import plan_from_references
from spm_console.store.plan_file import save_plan
from tests.support.ws_helpers import agile_profile

HOME = np.array([135.0, 135.0, 135.0])


def _line(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    return np.linspace(a, b, n)


def _forgeries() -> dict[str, np.ndarray]:
    """Self-consistent plans (positions follow the servo model) that break one rule each."""
    far = HOME + np.full(3, 24.5)  # legs 2 and 3 collide from θ = 159° on, inside the limits
    out = _line(HOME, far, 120)
    step = np.array([1.0, 0.0, 0.0])
    jump = np.vstack([_line(HOME, HOME + 5 * step, 40), np.repeat([HOME + 20 * step], 40, 0)])
    return {"link collision": np.vstack([out, out[::-1], np.repeat(HOME[None], 60, 0)]),
            "15° jump": jump}


@pytest.mark.parametrize("name", ["link collision", "15° jump"])
def test_a_forged_plan_is_refused_before_anything_is_powered(
        name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    prof = agile_profile()
    path = tmp_path / "forged.json"
    save_plan(plan_from_references(prof, _forgeries()[name], "synthetic"), path)
    logs = tmp_path / "logs"
    code = main(["execute", "--sim", "--sim-start", "130", "130", "130", "--plan", str(path),
                 "--logs", str(logs), "--json"])
    out, err = capsys.readouterr()
    assert code == ExitCode.PLAN_REFUSED, err
    reply = json.loads(out)
    assert reply["exit_code"] == ExitCode.PLAN_REFUSED
    assert "nothing moved" in reply["error"] and "Traceback" not in err
    assert ("workspace does not certify" if name == "link collision" else "jumps") in reply["error"]
    events = [json.loads(line) for f in logs.rglob("events.jsonl")
              for line in f.read_text().splitlines()]
    assert [e for e in events if e.get("event") in ("torque_on", "start")] == []
    runs = sorted(json.loads(f.read_text())["kind"] for f in logs.rglob("meta.json"))
    assert runs == ["execute"]  # the refused run's folder, and no homing run
