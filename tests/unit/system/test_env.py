"""One reading of the environment's off switches (real-time scheduling, the warm start)."""

from __future__ import annotations

import pytest

from spm_console.services.warm_start import ENV_WARM_START
from spm_console.system.env import switched_off
from spm_console.system.realtime import ENV_REALTIME


@pytest.mark.parametrize("name", [ENV_REALTIME, ENV_WARM_START])
@pytest.mark.parametrize(("value", "off"), [
    (None, False), ("", False), ("1", False), ("yes", False), ("offline", False),
    ("0", True), ("no", True), ("off", True), ("false", True), (" OFF ", True), ("False", True),
])
def test_each_switch_reads_the_same_words(monkeypatch: pytest.MonkeyPatch, name: str,
                                          value: str | None, off: bool) -> None:
    if value is None:
        monkeypatch.delenv(name, raising=False)
    else:
        monkeypatch.setenv(name, value)
    assert switched_off(name) is off


@pytest.mark.parametrize(("value", "expected"), [
    (None, None), ("", None), ("real", ("real", 0.0)), (" Simulated ", ("simulated", 0.0)),
    ("simulated:1", ("simulated", 1.0)), ("simulated:2.5", ("simulated", 2.5)),
])
def test_the_clock_override_reads_kind_and_pace(monkeypatch: pytest.MonkeyPatch,
                                                value: str | None,
                                                expected: tuple[str, float] | None) -> None:
    from spm_console.system.env import CLOCK_VAR, clock_override

    if value is None:
        monkeypatch.delenv(CLOCK_VAR, raising=False)
    else:
        monkeypatch.setenv(CLOCK_VAR, value)
    assert clock_override() == expected


@pytest.mark.parametrize("value", ["fake", "real:1", "simulated:", "simulated:0", "simulated:-1",
                                   "simulated:nan", "simulated:inf", "simulated:1e9", "simulated:x"])
def test_a_bad_clock_override_is_refused(monkeypatch: pytest.MonkeyPatch, value: str) -> None:
    from spm_console.system.env import CLOCK_VAR, clock_override

    monkeypatch.setenv(CLOCK_VAR, value)
    with pytest.raises(ValueError, match=CLOCK_VAR):
        clock_override()
