"""Identified profiles beside their profile: the layout of their names, never over a file, a
profile replaced only with a backup of it, the listing (each base profile, then its identified
ones newest first, with their fit figures), and the workspace cache a servo-only change reuses."""

from __future__ import annotations

import datetime as dt
import re
from pathlib import Path

import pytest

from spm_console.config.load import load_profile
from spm_console.config.schema import Identified, Profile, Servo
from spm_console.config.servo_section import with_servo
from spm_console.store.identified_profiles import (
    apply_in_place,
    arrange,
    base_name,
    family,
    identified_path,
    is_identified,
    stamp_of,
    write_beside,
)
from spm_console.store.workspace_cache import cache_key, cache_path
from spm_console.tui.screens.settings import list_profiles
from tests.support.paths import ROOT

AGILE = ROOT / "profiles" / "agile_wrist.toml"
NAME = re.compile(r"^agile_wrist\.identified-\d{4}-\d\d-\d\dT\d{6}Z(-\d+)?\.toml$")


def _date(minutes: int) -> str:
    when = dt.datetime(2026, 1, 1, tzinfo=dt.UTC) + dt.timedelta(minutes=minutes)
    return when.strftime("%Y-%m-%dT%H:%M:%SZ")


def _identified(profile: Profile, date: str, wn: float) -> tuple[str, Servo]:
    servo = Servo(p=wn, ts_s=profile.servo.ts_s, zeta=0.8, delay_s=0.003,
                  residual_bound_deg=0.2, identified=Identified(
                      date=date, source="logs/run", samples=300, fit_rms_deg=0.02,
                      held_out_rms_deg=0.03, held_out_max_deg=0.1))
    text, _ = with_servo(AGILE.read_text(encoding="utf-8"), servo, "test")
    return text, servo


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    d = tmp_path / "profiles"
    d.mkdir()
    (d / "agile_wrist.toml").write_bytes(AGILE.read_bytes())
    return d


def test_the_name_is_the_base_profiles_then_the_fit_time_and_sorts_by_time(folder: Path) -> None:
    base = folder / "agile_wrist.toml"
    first, later = identified_path(base, _date(0)), identified_path(base, _date(61))
    assert first.parent == folder and NAME.match(first.name) and NAME.match(later.name)
    assert sorted([later.name, first.name]) == [first.name, later.name]
    assert is_identified(first) and not is_identified(base)
    # an identification of an identified profile belongs to the same family
    assert base_name(first) == "agile_wrist" == base_name(base)
    assert identified_path(first, _date(61)) == later
    assert ":" not in stamp_of(_date(0))


def test_nothing_is_ever_written_over(folder: Path, agile: Profile) -> None:
    base = folder / "agile_wrist.toml"
    text_a, _ = _identified(agile, _date(0), 40.0)
    text_b, _ = _identified(agile, _date(0), 41.0)
    a = write_beside(base, text_a, _date(0))
    b = write_beside(base, text_b, _date(0))  # the same second: another name
    assert a != b and NAME.match(a.name) and NAME.match(b.name)
    assert a.read_text(encoding="utf-8") == text_a and b.read_text(encoding="utf-8") == text_b
    assert base.read_bytes() == AGILE.read_bytes()
    assert not [p for p in folder.iterdir() if p.name.startswith(".")]  # no temporary left
    assert load_profile(b).servo.p == 41.0


def test_apply_replaces_the_profile_and_keeps_it_as_it_was(folder: Path, agile: Profile) -> None:
    base = folder / "agile_wrist.toml"
    text, servo = _identified(agile, _date(0), 40.0)
    backup = apply_in_place(base, text, _date(0))
    assert backup.parent == folder and backup.name.startswith("agile_wrist.toml.bak-")
    assert backup.read_bytes() == AGILE.read_bytes()
    assert load_profile(base).servo == servo
    again = apply_in_place(base, text, _date(0))  # the backup's name taken: another one
    assert again != backup and again.read_text(encoding="utf-8") == text
    assert backup.read_bytes() == AGILE.read_bytes()
    assert [e.path.name for e in list_profiles(None, [folder])] == ["agile_wrist.toml"]


def test_each_profile_is_listed_with_its_identified_ones_newest_first(
        folder: Path, agile: Profile) -> None:
    base = folder / "agile_wrist.toml"
    (folder / "coaxial_spm.toml").write_bytes((ROOT / "profiles" / "coaxial_spm.toml").read_bytes())
    written = [write_beside(base, _identified(agile, _date(m), wn)[0], _date(m))
               for m, wn in ((0, 40.0), (120, 42.0), (60, 41.0))]
    oldest, newest, middle = written
    entries = list_profiles(None, [folder])
    assert [e.path for e in entries] == [base, newest, middle, oldest,
                                         folder / "coaxial_spm.toml"]
    assert entries[0].fit is None and entries[4].fit is None
    assert [e.fit.wn_radps for e in entries[1:4] if e.fit] == [42.0, 41.0, 40.0]
    label = entries[1].label()
    assert str(newest) in label and all(w in label for w in ("identified", "ωn", "ζ",
                                                              "held-out RMS"))
    # a profile in use elsewhere brings its family: the base and every identification
    assert [e.path for e in list_profiles(middle, [])] == [base, newest, middle, oldest]
    assert family(oldest) == [base, newest, middle, oldest]
    assert arrange([oldest, base, oldest]) == [base, oldest]


def test_a_servo_only_change_keeps_the_workspace_cache(agile: Profile, tmp_path: Path) -> None:
    """The identified profile's workspace is the cached one: same key, same file."""
    _, servo = _identified(agile, _date(0), 40.0)
    identified = agile.model_copy(update={"servo": servo})
    assert identified.servo != agile.servo
    assert cache_key(identified) == cache_key(agile)
    assert cache_path(identified, tmp_path) == cache_path(agile, tmp_path)
