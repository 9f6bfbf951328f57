"""Fixtures of the console tests: the app from the one factory, on the emulated bus,
without the 3D view, with its own log folder and a workspace cache built once."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import pytest
from textual import constants

from spm_console.config.schema import Profile
from spm_console.tui.app import SpmConsoleApp, make_app


@pytest.fixture(autouse=True)
def _no_animations(monkeypatch: pytest.MonkeyPatch) -> None:
    """Apps made in a console test do not animate: a field focused below the fold is scrolled
    to at once, not over a few frames. Textual's pilot waits for a 20 ms window with under
    1 ms of CPU, which the frames of a cheap animation leave, so a test could read the screen
    mid-scroll. (``TEXTUAL_ANIMATIONS`` in the environment comes too late: the snapshot plugin
    loads Textual before any conftest; an app reads the constant when it is made.)"""
    monkeypatch.setattr(constants, "TEXTUAL_ANIMATIONS", "none")


@pytest.fixture(scope="session")
def ws_cache(tmp_path_factory: pytest.TempPathFactory, agile: Profile) -> Path:
    """A workspace cache folder holding the Agile Wrist workspace (built once per run)."""
    from tests.support.ws_helpers import cache_folder_holding

    return cache_folder_holding(agile, tmp_path_factory.mktemp("ws-cache"))


@pytest.fixture
def console(agile: Profile, ws_cache: Path, tmp_path: Path) -> Callable[..., SpmConsoleApp]:
    """``console(initial_deg=..., faults=...)`` -> a fresh app (emulated bus, no viewer)."""

    def build(initial_deg: Sequence[float] | None = None, logs_root: Path | None = None,
              **kw: Any) -> SpmConsoleApp:
        return make_app(agile, sim=True, viewer=False, logs_root=logs_root or tmp_path / "logs",
                        cache_dir=ws_cache, initial_deg=initial_deg, **kw)

    return build


@pytest.fixture(autouse=True)
def _own_form_memory(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each console test starts with no remembered form values (and keeps its own)."""
    monkeypatch.setenv("SPM_CONSOLE_CONFIG", str(tmp_path / "config"))
