"""How the console looks: a few committed SVG snapshots (update with --snapshot-update).

Nondeterminism is frozen: no 3D view, the emulated bus (fixed temperatures and
voltages, quantized positions), no timings or paths on these screens, and real-time
scheduling switched off (SPM_CONSOLE_REALTIME=0: whether a machine grants SCHED_FIFO must
not change what the snapshots show).
"""

from __future__ import annotations

from typing import Any

import pytest
from textual.pilot import Pilot

from spm_console.tui.widgets.angles import AnglesInput
from tests.tui.helpers import settle

SIZE = (120, 34)


@pytest.fixture(autouse=True)
def _no_realtime(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SPM_CONSOLE_REALTIME", "0")


def test_connect_screen_after_connecting(snap_compare: Any, console: Any) -> None:
    async def run_before(pilot: Pilot[Any]) -> None:
        await settle(pilot)

    assert snap_compare(console(), terminal_size=SIZE, run_before=run_before)


def test_home_confirmation(snap_compare: Any, console: Any) -> None:
    async def run_before(pilot: Pilot[Any]) -> None:
        await settle(pilot)
        await pilot.press("h")
        await pilot.pause()

    assert snap_compare(console(), terminal_size=SIZE, run_before=run_before)


def test_fk_of_the_paper_example(snap_compare: Any, console: Any) -> None:
    async def run_before(pilot: Pilot[Any]) -> None:
        await settle(pilot)
        await pilot.press("2")
        pilot.app.screen.query_one("#theta", AnglesInput).set_values([95, 110, 105])
        await pilot.press("f")
        await settle(pilot)

    assert snap_compare(console(), terminal_size=SIZE, run_before=run_before)
