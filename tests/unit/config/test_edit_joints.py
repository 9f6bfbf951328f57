"""Setting the ``[[bus.joints]]`` tables of a profile's text: each table its own values,
everything else kept, the result parsed and read back."""

from __future__ import annotations

import pytest

from spm_console.config.edit import with_joints
from spm_console.errors import ProfileError
from tests.support.paths import ROOT

TEXT = (ROOT / "profiles" / "agile_wrist.toml").read_text()


def test_each_joint_table_gets_its_own_values_and_the_rest_is_kept() -> None:
    new, prof = with_joints(TEXT, [{"id": 3, "direction": -1, "tick_offset": 3584}, {"id": 1},
                                   {"id": 2, "tick_offset": 600}], "as built", "test")
    assert [(j.id, j.direction, j.tick_offset) for j in prof.bus.joints] == [
        (3, -1, 3584), (1, 1, 512), (2, 1, 600)]
    removed = set(TEXT.splitlines()) - set(new.splitlines())
    assert all(line.split("=")[0].strip() in ("id", "tick_offset", "direction")
               for line in removed)
    assert new.count("# as built") == 6


def test_a_profile_that_would_not_validate_is_refused() -> None:
    with pytest.raises(ProfileError):  # direction -1 from tick 512: the limits' ticks < 0
        with_joints(TEXT, [{"direction": -1}, {}, {}], "as built", "test")


def test_another_number_of_tables_is_refused() -> None:
    with pytest.raises(ProfileError, match=r"3 \[\[bus\.joints\]\] tables, expected 2"):
        with_joints(TEXT, [{}, {}], "as built", "test")
