"""identify --csv --load: the experiment's structure (ωn, ζ, delay, load) fitted to a record."""

from __future__ import annotations

import functools
import json
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.config.load import load_profile
from spm_console.core.servo.experiment import excitation
from spm_console.core.servo.identify import response
from spm_console.core.servo.load import LoadModel
from spm_console.core.servo.load_fit import model_velocity
from spm_console.core.servo.model import Dynamics
from spm_console.description.weight import holding_torque_nm
from spm_console.errors import ExitCode
from tests.support.paths import ROOT

DYN = Dynamics(39.0, 0.77, 0.001)
LOAD = LoadModel(np.array([1.39]), 0.085)


@functools.cache
def _record() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, reference, measured) of the loaded model about home: the weight's offset at the
    poses it reaches (iterated to its fixed point: the load depends on where the servo is).
    Computed once: every test reads the same record."""
    profile = load_profile(ROOT / "profiles" / "agile_wrist.toml")
    home = np.full(3, 135.0)
    ex = excitation(home, 0.02, 6.0, 120.0)
    ref = ex.reference_deg[:700]
    t = 3.0 + np.arange(len(ref)) * 0.02
    vel = model_velocity(DYN, t, ref, home)
    meas = ref.copy()
    for _ in range(4):
        d = LOAD.offset_deg(holding_torque_nm(profile, meas)[:, :, None], vel)
        meas = response(DYN, DYN.delay_s, t - t[0], ref - d, home - d[0])
    return t, ref, meas


def _csv(tmp_path: Path, joints: int = 3) -> Path:
    """The record as a CSV of ``joints`` joints."""
    t, ref, meas = _record()
    cols = ["t", *(f"ref{i + 1}" for i in range(joints)), *(f"meas{i + 1}" for i in range(joints))]
    rows = [",".join(cols)]
    rows += [",".join(f"{v:.9f}" for v in (t[k], *ref[k, :joints], *meas[k, :joints]))
             for k in range(len(t))]
    f = tmp_path / "loaded.csv"
    f.write_text("\n".join(rows) + "\n")
    return f


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_the_load_is_fitted_from_a_csv(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    f = _csv(tmp_path)
    code, so, _ = _run(capsys, "identify", "--csv", str(f), "--load", "--json")
    assert code == 0
    d = json.loads(so)
    assert d["p"] == pytest.approx(DYN.wn, rel=0.01)
    assert d["zeta"] == pytest.approx(DYN.zeta, rel=0.01)
    assert d["load_deg_per_nm"] == pytest.approx(1.39, rel=0.05)
    assert d["coulomb_deg"] == pytest.approx(0.085, abs=0.01)
    code, so, _ = _run(capsys, "identify", "--csv", str(f), "--damping", "--delay", "--json")
    plain = json.loads(so)
    assert "load_deg_per_nm" not in plain and plain["rms_deg"] > 3 * d["rms_deg"]


def test_load_needs_three_joints_and_no_other_structure_flag(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    code, _, err = _run(capsys, "identify", "--csv", str(_csv(tmp_path, joints=2)), "--load")
    assert code == ExitCode.BAD_INPUT and "three joints" in err
    code, _, err = _run(capsys, "identify", "--csv", str(_csv(tmp_path)), "--load", "--delay")
    assert code == ExitCode.USAGE and "--load" in err  # options that do not go together


def test_load_refuses_poses_outside_the_servo_limits_and_jumps(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """The load is followed pose by pose: a record beyond the wrist's servo limits, or one that
    leaps between samples, is refused before any FK (no traceback, no hour-long walk)."""
    good = _csv(tmp_path).read_text().splitlines()
    for name, meas in (("far", ["3000", "135", "135"]), ("leap", ["160", "120", "150"])):
        lines = list(good)
        cells = lines[300].split(",")
        lines[300] = ",".join(cells[:4] + meas)  # one measured pose replaced
        f = tmp_path / f"{name}.csv"
        f.write_text("\n".join(lines) + "\n")
        code, _, err = _run(capsys, "identify", "--csv", str(f), "--load")
        assert code == ExitCode.BAD_INPUT, err
        assert ("servo limits" if name == "far" else "between samples") in err
        assert "Traceback" not in err
