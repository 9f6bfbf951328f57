"""The operator session loads a saved plan exactly as the runtime will take it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from spm_console.config.schema import Profile
from spm_console.errors import ExitCode, PlanMismatchError, SpmError
from spm_console.services.session import PoseSpec, Session
from spm_console.store.plan_file import save_plan


def test_a_saved_plan_loads_verified_and_a_foreign_one_is_refused(
        agile: Profile, tmp_path: Path) -> None:
    s = Session(agile, sim=True, logs_root=tmp_path / "logs")
    s.load_workspace()
    plan = s.solve_plan("mvn", PoseSpec("home"), PoseSpec("theta", (125.0, 130.0, 128.0)), 40)
    assert s.plan_info is not None and s.plan_info.region.startswith("the workspace region P (")
    path = tmp_path / "p.json"
    save_plan(plan, path)
    s.plan = None
    loaded = s.load_plan_file(path)
    assert s.plan is loaded and s.plan_source == str(path)
    np.testing.assert_array_equal(loaded.reference_deg, plan.reference_deg)
    # a plan for another profile version (its hash differs): refused, current plan kept
    foreign = plan.__class__(**{**plan.__dict__, "profile_hash": "0" * 64})
    save_plan(foreign, tmp_path / "foreign.json")
    with pytest.raises(PlanMismatchError) as exc:
        s.load_plan_file(tmp_path / "foreign.json")
    assert exc.value.exit_code == ExitCode.PLAN_MISMATCH and s.plan is loaded
    with pytest.raises(SpmError):
        s.load_plan_file(tmp_path / "missing.json")
