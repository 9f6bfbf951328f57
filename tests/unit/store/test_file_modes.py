"""Every file the console writes has the permissions the umask gives a new file: 0644 under the
usual 022, 0600 under 077. Files replaced atomically (a temporary file renamed onto the name:
run.mcap and metadata.yaml, meta.json, exported URDF and MJCF, plans, the workspace cache, the console's memory)
as much as those written in place (samples.csv, events.jsonl)."""

from __future__ import annotations

import json
import os
import stat
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.config.schema import Profile
from spm_console.motion.logs.mcap_log import write_run_mcap
from spm_console.motion.logs.runlog import RunLog
from spm_console.motion.plans import synthetic_plan
from spm_console.motion.sample import Sample
from spm_console.store.form_memory import FormMemory
from spm_console.store.plan_file import save_plan
from spm_console.store.workspace_cache import save
from tests.support.ws_helpers import coarse_workspace


@pytest.fixture(params=[0o022, 0o077, 0o002], ids=lambda m: f"umask {m:03o}")
def umask(request: pytest.FixtureRequest) -> Iterator[int]:
    old = os.umask(request.param)
    try:
        yield int(request.param)
    finally:
        os.umask(old)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def _expect(files: list[Path], umask: int) -> None:
    """Each file's mode is what open() gives a new file under ``umask``: rw for everyone the
    umask leaves, never execute."""
    want = 0o666 & ~umask
    got = {p.name: oct(_mode(p)) for p in files}
    assert got == {p.name: oct(want) for p in files}


def _run(root: Path, agile: Profile) -> Path:
    log = RunLog.create("execute", agile.name, agile.digest(), [], root=root)
    home = np.array(agile.home.theta_deg, float)
    for k in range(3):
        log.sample(Sample(t=0.02 * k, k=k, phase="plan", reference_deg=home, measured_deg=home,
                          predicted_deg=home, predicted_velocity_degps=home * 0, filtered_deg=home,
                          velocity_degps=home * 0, fd_velocity_degps=home * 0,
                          tracking_error_deg=0.0, bus_s=0.001, late_s=0.0, retries=0))
    log.event("start", 0.0)
    log.finish("completed", 0, "", {})
    return log.path


def test_a_run_folder(tmp_path: Path, agile: Profile, umask: int) -> None:
    run = _run(tmp_path, agile)
    mcap = write_run_mcap(run, agile).path
    files = sorted(run.iterdir())
    assert {p.name for p in files} == {"meta.json", "samples.csv", "events.jsonl", mcap.name,
                                       "metadata.yaml"}
    _expect(files, umask)


def test_exported_descriptions_and_plans(tmp_path: Path, agile: Profile, umask: int,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    urdf, mjcf, plan = tmp_path / "wrist.urdf", tmp_path / "wrist.xml", tmp_path / "plan.json"
    assert main(["export", "urdf", "--out", str(urdf), "--json"]) == 0
    assert main(["export", "mjcf", "--out", str(mjcf), "--json"]) == 0
    assert all(json.loads(line)["ok"] for line in capsys.readouterr().out.splitlines())
    home = np.array(agile.home.theta_deg, float)
    save_plan(synthetic_plan(agile, home, home + 2.0, 0.5), plan)
    save_plan(synthetic_plan(agile, home, home + 3.0, 0.5), plan)  # replaced: the same mode
    _expect([urdf, mjcf, plan], umask)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.json", "wrist.urdf", "wrist.xml"]


def test_the_workspace_cache_and_the_consoles_memory(tmp_path: Path, umask: int) -> None:
    cache, memory = tmp_path / "workspace.npz", tmp_path / "console.json"
    save(coarse_workspace(), cache, "key")
    form = FormMemory(memory)
    form.put("agile_wrist", "steps", "40")
    assert form.save(), form.error
    _expect([cache, memory], umask)
