"""The operator session loads a saved plan exactly as the runtime will take it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from spm_console.config.schema import Profile
from spm_console.errors import ExitCode, PlanMismatchError, SpmError
from spm_console.services.session import Session
from spm_console.services.wrist_service import PoseSpec
from spm_console.store.plan_file import save_plan


def test_a_saved_plan_loads_verified_and_a_foreign_one_is_refused(
        agile: Profile, tmp_path: Path) -> None:
    s = Session(agile, sim=True, logs_root=tmp_path / "logs")
    s.wrist.load_workspace()
    plan = s.plans.solve("mvn", PoseSpec("home"), PoseSpec("theta", (125.0, 130.0, 128.0)),
                          steps=40)
    assert s.plans.info is not None and s.plans.info.region.startswith("the workspace region P (")
    path = tmp_path / "p.json"
    save_plan(plan, path)
    s.plans.plan = None
    loaded = s.plans.open(path)
    assert s.plans.plan is loaded and s.plans.source == str(path)
    np.testing.assert_array_equal(loaded.reference_deg, plan.reference_deg)
    # a plan for another profile version (its hash differs): refused, current plan kept
    foreign = plan.__class__(**{**plan.__dict__, "profile_hash": "0" * 64})
    save_plan(foreign, tmp_path / "foreign.json")
    with pytest.raises(PlanMismatchError) as exc:
        s.plans.open(tmp_path / "foreign.json")
    assert exc.value.exit_code == ExitCode.PLAN_MISMATCH and s.plans.plan is loaded
    with pytest.raises(SpmError):
        s.plans.open(tmp_path / "missing.json")
