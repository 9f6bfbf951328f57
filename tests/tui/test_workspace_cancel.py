"""Step 3: a running workspace load/build is cancelled by `c` at its next progress report;
the workspace loaded before stays in use and nothing half-built reaches the cache."""

from __future__ import annotations

import hashlib
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

import spm_console.store.workspace_cache as workspace_cache
from spm_console.config.load import with_grid_step
from spm_console.config.schema import Profile
from spm_console.tui.app import make_app
from tests.support.console_helpers import settle, status_of, text_of

SIZE = (120, 40)


class Gate:
    """Holds the build at its first progress report until the test has pressed its key,
    so the cancel lands mid-build on any machine (then counts the reports that follow)."""

    def __init__(self) -> None:
        self.active = False
        """Builds pass straight through until a test sets this."""
        self.reached = threading.Event()
        self.release = threading.Event()
        self.reports_after = 0

    def wrap(self, real: Callable[..., Any]) -> Callable[..., Any]:
        def build(profile: Profile, progress: Any = None) -> Any:
            def gated(stage: str, fraction: float) -> None:
                if self.active and not self.reached.is_set():
                    self.reached.set()
                    self.release.wait(60)
                elif self.active:
                    self.reports_after += 1
                progress(stage, fraction)

            return real(profile, gated if progress is not None else None)

        return build


@pytest.fixture
def gate(monkeypatch: pytest.MonkeyPatch) -> Iterator[Gate]:
    g = Gate()
    monkeypatch.setattr(workspace_cache, "build_workspace", g.wrap(workspace_cache.build_workspace))
    yield g
    g.release.set()  # never leave a worker waiting


@pytest.fixture
def coarse(agile: Profile) -> Profile:
    """The Agile Wrist on a 5° grid: a quick build."""
    return with_grid_step(agile, 5.0)


async def _until_held(pilot: Any, gate: Gate, timeout_s: float = 60.0) -> None:
    """Pump the app until the build reaches the gate (bounded: fails, never hangs)."""
    t_end = time.monotonic() + timeout_s
    while not gate.reached.is_set():
        assert time.monotonic() < t_end, f"the build did not reach the gate within {timeout_s:.0f} s"
        await pilot.pause(0.02)


async def _cancel_when_held(pilot: Any, gate: Gate) -> None:
    await _until_held(pilot, gate)
    assert "c cancels" in status_of(pilot.app)
    await pilot.press("c")
    assert "cancelling the build" in status_of(pilot.app)
    gate.release.set()
    await settle(pilot, timeout_s=120)


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


async def test_cancelled_rebuild_keeps_the_workspace_and_the_cache(coarse: Profile,
                                                                    tmp_path: Path,
                                                                    gate: Gate) -> None:
    cache = tmp_path / "cache"
    workspace_cache.load_or_build(coarse, cache_dir=cache)
    cache_file = workspace_cache.cache_path(coarse, cache)
    before = (_digest(cache_file), cache_file.stat().st_mtime_ns)
    gate.active = True

    app = make_app(coarse, viewer=False, logs_root=tmp_path / "logs", cache_dir=cache)
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("3")
        await settle(pilot)
        loaded = app.session.wrist.workspace
        assert loaded is not None and text_of(app, "#ws-info").startswith("loaded from the cache")
        await pilot.press("b")
        await pilot.press("y")  # rebuild from scratch
        await _cancel_when_held(pilot, gate)

        # the held report, the first the console got after `c`, raised: no report followed
        assert gate.reports_after == 0
        assert app.session.wrist.workspace is loaded  # the workspace loaded before stays in use
        assert app.build_cancel is None
        assert "build cancelled" in status_of(app)
        assert "stays in use" in status_of(app)
        assert text_of(app, "#ws-stage") == "build cancelled"
        assert text_of(app, "#ws-info").startswith("loaded from the cache")
        assert not app.screen.query_one("#ws-progress").display
        # nothing half-built was cached: the file is the one written before, no temp file left
        assert (_digest(cache_file), cache_file.stat().st_mtime_ns) == before
        assert sorted(p.name for p in cache.iterdir()) == [cache_file.name]

        await pilot.press("k")  # the kept workspace answers checks
        await settle(pilot)
        assert "plannable in P" in text_of(app, "#ws-check")


async def test_cancelled_first_build_leaves_no_workspace_and_no_cache(coarse: Profile,
                                                                      tmp_path: Path,
                                                                      gate: Gate) -> None:
    cache = tmp_path / "cache"
    gate.active = True
    app = make_app(coarse, viewer=False, logs_root=tmp_path / "logs", cache_dir=cache)
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("3")  # no cache: the screen starts building
        await _cancel_when_held(pilot, gate)
        assert app.session.wrist.workspace is None
        assert "build cancelled" in status_of(app)
        assert "the build was cancelled" in text_of(app, "#ws-info")
        assert not cache.exists() or not any(cache.iterdir())


async def test_c_outside_a_build_does_nothing(coarse: Profile, tmp_path: Path,
                                                gate: Gate) -> None:
    cache = tmp_path / "cache"
    workspace_cache.load_or_build(coarse, cache_dir=cache)
    app = make_app(coarse, viewer=False, logs_root=tmp_path / "logs", cache_dir=cache)
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("3")
        await settle(pilot)
        assert app.screen.check_action("cancel_build", ()) is False  # not in the footer
        ready = status_of(app)
        await pilot.press("c")
        await settle(pilot)
        assert status_of(app) == ready


async def test_quitting_during_a_build_cancels_it(coarse: Profile, tmp_path: Path,
                                                  gate: Gate) -> None:
    """The app's exit waits for its worker threads: quitting cancels the build rather than
    waiting for it to finish (and caches nothing)."""
    cache = tmp_path / "cache"
    gate.active = True
    app = make_app(coarse, viewer=False, logs_root=tmp_path / "logs", cache_dir=cache)
    async with app.run_test(size=SIZE) as pilot:
        await settle(pilot)
        await pilot.press("3")
        await _until_held(pilot, gate)
        await pilot.press("q", "q")  # asked first, then quit
        assert app.build_cancel is not None and app.build_cancel.is_set()
        gate.release.set()
    assert app.return_code == 0
    assert gate.reports_after == 0
    assert not cache.exists() or not any(cache.iterdir())
