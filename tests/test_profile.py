"""Profiles: the shipped ones load; each kind of broken file names file, key and reason."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from spm_console.errors import ExitCode, ProfileError
from spm_console.profile import load_profile

DATA = Path(__file__).parent / "data" / "profiles"


def test_shipped_profiles_load(agile, coaxial) -> None:  # type: ignore[no-untyped-def]
    assert agile.name == "agile_wrist"
    assert agile.geometry.beta_deg == pytest.approx(math.degrees(math.acos(1 / math.sqrt(3))), abs=1e-12)
    assert agile.home.theta_deg == (135.0, 135.0, 135.0)
    assert agile.home.sign_seed == (-1, 1, 1, 1, 1, 1, -1, -1, 1)
    assert agile.workspace.axis_deg[0] == 65.0 and agile.workspace.axis_deg[-1] == 155.0
    assert len(agile.workspace.axis_deg) == 46
    assert agile.servo.p == 32.22 and agile.servo.ts_s == 0.02
    assert coaxial.geometry.gamma_deg == 0.0


def test_digest_is_stable_and_sensitive(agile) -> None:  # type: ignore[no-untyped-def]
    again = load_profile("profiles/agile_wrist.toml")
    assert again.digest() == agile.digest()
    changed = agile.model_copy(update={"servo": agile.servo.model_copy(update={"p": 30.0})})
    assert changed.digest() != agile.digest()


@pytest.mark.parametrize(
    ("fixture", "key", "reason"),
    [
        ("bad_toml.toml", None, "not valid TOML"),
        ("missing_key.toml", "servo.p", "missing key"),
        ("wrong_type.toml", "servo.ts_s", "valid number"),
        ("out_of_range.toml", "workspace.zeta_min", "less than 1"),
        ("unknown_key.toml", "servo.gain", "unknown key"),
        ("home_outside_limits.toml", "bus.joints[1]", "outside the servo limits"),
        ("duplicate_ids.toml", "bus", "distinct servo ids"),
    ],
)
def test_broken_profile_names_file_key_reason(fixture: str, key: str | None, reason: str) -> None:
    path = DATA / fixture
    with pytest.raises(ProfileError) as info:
        load_profile(path)
    msg = info.value.message
    assert str(path) in msg
    if key is not None:
        assert f"'{key}'" in msg
    assert reason in msg
    assert info.value.exit_code == ExitCode.PROFILE_ERROR


def test_missing_file() -> None:
    with pytest.raises(ProfileError, match="cannot read profile"):
        load_profile("profiles/does_not_exist.toml")
