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
