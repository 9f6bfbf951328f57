"""Fixtures of the runtime tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from spm_console.config.schema import Profile
from spm_console.devices.emulator.bus import EmulatorHandle, start_emulator


@pytest.fixture
def bus(agile: Profile) -> Iterator[EmulatorHandle]:
    """An emulated bus of the agile profile's wrist, at home, not recorded."""
    em = start_emulator(agile, record=False)
    try:
        yield em
    finally:
        em.stop()
