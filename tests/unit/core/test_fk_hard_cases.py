"""Hard cases for unique FK (tests/data/fk_hard_cases.csv): the paper's fixed-seed solve
lands in another assembly mode (or fails) while continuation gives the home mode."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from spm_console.core.kinematics.model import SpmModel
from spm_console.core.kinematics.modes import assembly_modes, seeded_solve
from tests.support.paths import TESTS
from tests.support.ws_helpers import agile_profile, agile_workspace

DATA = TESTS / "data" / "fk_hard_cases.csv"


def _rows() -> list[dict[str, str]]:
    lines = [ln for ln in DATA.read_text().splitlines() if not ln.startswith("#")]
    return list(csv.DictReader(lines))


ROWS = _rows()


def _v(row: dict[str, str], prefix: str) -> np.ndarray:
    return np.array([float(row[f"{prefix}{r}{c}"]) for r in range(1, 4) for c in "xyz"]).reshape(3, 3)


def test_file_is_small_and_varied() -> None:
    assert 10 <= len(ROWS) <= 200
    outcomes = {r["seeded_outcome"] for r in ROWS}
    assert "other_mode" in outcomes
    assert any(float(r["zeta"]) > 0.5 for r in ROWS)  # well-conditioned nodes too


@pytest.mark.parametrize("row", ROWS, ids=lambda r: f"{r['theta1_deg']}-{r['theta2_deg']}-{r['theta3_deg']}")
def test_continuation_and_seeded_solve(row: dict[str, str], agile_model: SpmModel) -> None:
    model = agile_model
    th = np.radians([float(row[f"theta{i}_deg"]) for i in (1, 2, 3)])
    v_ref = _v(row, "v")
    # continuation, two ways: straight from home (when that path avoids singularities),
    # else the flood-filled grid continued from its neighbours
    r = model.track(th)
    if r.ok and r.pose is not None:
        v = r.pose.v
    else:
        ws = agile_workspace()
        idx = ws.index_of(np.degrees(th))
        assert idx is not None
        v = np.einsum("ab,ib->ia", ws.R[idx], model.v_home)
    assert np.abs(v - v_ref).max() < 1e-9
    # the paper's seeded solve really disagrees, as recorded
    x0 = np.asarray(agile_profile().home.sign_seed, float)
    vs, ok = seeded_solve(model.geom, th, x0)
    assert (not ok) or np.abs(vs - v_ref).max() > 1e-6
    assert int(row["seeded_converged"]) == int(ok)
    if ok:
        assert np.abs(vs - _v(row, "seeded_v")).max() < 1e-7


def test_other_mode_is_a_real_solution(agile_model: SpmModel) -> None:
    """For one well-conditioned case, both the seeded and the continuation answers are
    among the assembly modes found independently (multi-start LM)."""
    row = max((r for r in ROWS if r["seeded_outcome"] == "other_mode"), key=lambda r: float(r["zeta"]))
    th = np.radians([float(row[f"theta{i}_deg"]) for i in (1, 2, 3)])
    modes = assembly_modes(agile_model, th)
    for v in (_v(row, "v"), _v(row, "seeded_v")):
        assert min(np.abs(m.v - v).max() for m in modes) < 1e-6
