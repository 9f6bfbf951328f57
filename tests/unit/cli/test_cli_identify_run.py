"""identify --run fits a run of the wrist the profile describes: a run logged with another
wrist's profile is refused (exit 4) naming both; it used to be fitted without a word."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.config.load import load_profile
from spm_console.config.schema import Profile
from spm_console.core.servo.identify import response
from spm_console.core.servo.model import Dynamics
from spm_console.errors import ExitCode
from spm_console.motion.logs.profile_record import wrist_digests
from spm_console.motion.logs.runlog import RunLog
from spm_console.motion.sample import Sample
from tests.support.paths import ROOT

AGILE = ROOT / "profiles" / "agile_wrist.toml"
COAXIAL = ROOT / "profiles" / "coaxial_spm.toml"
TS = 0.02


def _run(root: Path, profile: Profile, wrist: bool = True, name: str | None = None,
         digest: str | None = None) -> Path:
    """A run of ``profile``'s servos (p = 32.22) stepping 5° from home, logged as the runtime
    logs one (``wrist``: with its wrist's digests, as runs now record them)."""
    home = np.asarray(profile.home.theta_deg, float)
    t = np.arange(60) * TS
    ref = np.tile(home, (len(t), 1))
    ref[5:] += 5.0
    meas = response(Dynamics(32.22, 1.0, 0.0), 0.0, t, ref, home)
    log = RunLog.create("execute", name or profile.name, digest or profile.digest(), [],
                        root=root, wrist=wrist_digests(profile) if wrist else None)
    z = np.zeros(3)
    for k in range(len(t)):
        log.sample(Sample(t=float(t[k]), k=k, phase="plan", reference_deg=ref[k],
                          measured_deg=meas[k], predicted_deg=meas[k], predicted_velocity_degps=z,
                          filtered_deg=meas[k], velocity_degps=z, fd_velocity_degps=z,
                          tracking_error_deg=0.0, bus_s=1e-3, late_s=0.0))
    log.finish("completed", 0, "done", {})
    return log.path


def _identify(capsys: pytest.CaptureFixture[str], run: Path, profile: Path) -> tuple[int, str]:
    code = main(["identify", "--run", str(run), "--profile", str(profile), "--json"])
    out = capsys.readouterr()
    if code == 0:
        assert json.loads(out.out)["p"] == pytest.approx(32.22, rel=0.01)
    return code, out.err


def _variant(tmp_path: Path, old: str, new: str) -> Path:
    text = AGILE.read_text()
    assert old in text
    path = tmp_path / f"variant{len(list(tmp_path.glob('variant*')))}.toml"
    path.write_text(text.replace(old, new, 1))
    return path


def test_a_run_of_another_wrist_is_refused_naming_both(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    run = _run(tmp_path / "logs", load_profile(AGILE))
    code, err = _identify(capsys, run, COAXIAL)
    assert code == ExitCode.BAD_INPUT, err
    assert "profile 'agile_wrist'" in err and f"profile 'coaxial_spm' ({COAXIAL})" in err
    assert "in geometry, home, bus" in err and "--profile" in err and "Traceback" not in err


def test_another_servo_wiring_is_another_wrist(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    run = _run(tmp_path / "logs", load_profile(AGILE))
    rewired = _variant(tmp_path, "id = 1 ", "id = 7 ")
    code, err = _identify(capsys, run, rewired)
    assert code == ExitCode.BAD_INPUT and "differs from profile 'agile_wrist'" in err and \
        "in bus;" in err, err


def test_the_same_wrist_identified_again_or_on_another_port_still_fits(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """The servo model, the port and the name are what a profile says about the wrist or how
    it is reached: a run logged before the wrist was identified again is its record."""
    run = _run(tmp_path / "logs", load_profile(AGILE))
    assert _identify(capsys, run, AGILE) == (0, "")
    for old, new in (("p = 32.22 ", "p = 30.5 "), ('port = ""', 'port = "/dev/ttyUSB1"'),
                     ('name = "agile_wrist"', 'name = "agile_wrist_2"')):
        code, err = _identify(capsys, run, _variant(tmp_path, old, new))
        assert code == 0 and "note" not in err, (old, err)


def test_a_run_older_than_the_wrists_record_is_checked_by_its_profiles_name(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    agile = load_profile(AGILE)
    same = _run(tmp_path / "logs", agile, wrist=False)
    assert _identify(capsys, same, AGILE) == (0, "")
    edited = _run(tmp_path / "logs", agile, wrist=False, digest="0" * 64)
    code, err = _identify(capsys, edited, AGILE)
    assert code == 0 and "note:" in err and "another version of profile 'agile_wrist'" in err
    other = _run(tmp_path / "logs", agile, wrist=False, name="coaxial_spm", digest="0" * 64)
    code, err = _identify(capsys, other, AGILE)
    assert code == ExitCode.BAD_INPUT and "logged with profile 'coaxial_spm', not profile " \
                                          "'agile_wrist'" in err, err


def test_a_run_that_records_no_profile_is_fitted_with_a_note(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    run = _run(tmp_path / "logs", load_profile(AGILE))
    (run / "meta.json").unlink()
    code, err = _identify(capsys, run, AGILE)
    assert code == 0 and "records no profile" in err, err
