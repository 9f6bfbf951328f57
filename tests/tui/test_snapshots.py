"""How the console looks: a few committed SVG snapshots (update with --snapshot-update).

Nondeterminism is frozen: no 3D view, the emulated bus (fixed temperatures and
voltages, quantized positions), no timings or paths on these screens, and real-time
scheduling switched off (SPM_CONSOLE_REALTIME=0: whether a machine grants SCHED_FIFO must
not change what the snapshots show).
"""

from __future__ import annotations

import fcntl
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from textual.pilot import Pilot

from spm_console.tui.widgets.angles import AnglesInput
from tests.support.console_helpers import settle

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


#: Every screen at the smallest supported terminal and a large one (issue 13).
SIZES = {"80x24": (80, 24), "160x48": (160, 48)}
#: The Logs screen names its root: a fixed, empty folder keeps the picture the same everywhere.
LOGS = Path(tempfile.gettempdir()) / "spm-console-snapshot-logs"
#: The Workspace screen names its cache file: the same, with a fixed folder.
CACHE = Path(tempfile.gettempdir()) / "spm-console-snapshot-cache"


@pytest.fixture
def _fixed_folders() -> Iterator[None]:
    """The fixed folders are shared by every test session on the machine: one at a time."""
    with open(Path(tempfile.gettempdir()) / "spm-console-snapshot.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


@pytest.mark.usefixtures("_fixed_folders")
@pytest.mark.parametrize("size", list(SIZES), ids=list(SIZES))
@pytest.mark.parametrize("step", ["f1", "f2", "f3", "f4", "f5", "f6", "help"])
def test_every_screen_at_80x24_and_160x48(snap_compare: Any, agile: Any, ws_cache: Path,
                                         step: str, size: str) -> None:
    """Each step as it first shows (connected, nothing run yet, no runs logged) and the help
    screen: no run, plan, timing or temporary path on them, so nothing machine-dependent."""
    from spm_console.tui.app import make_app

    shutil.rmtree(LOGS, ignore_errors=True)
    LOGS.mkdir()
    shutil.rmtree(CACHE, ignore_errors=True)
    shutil.copytree(ws_cache, CACHE)

    async def run_before(pilot: Pilot[Any]) -> None:
        await settle(pilot)
        await pilot.press("question_mark" if step == "help" else step)
        await settle(pilot)

    app = make_app(agile, sim=True, viewer=False, logs_root=LOGS, cache_dir=CACHE)
    assert snap_compare(app, terminal_size=SIZES[size], run_before=run_before)
