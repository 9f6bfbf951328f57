"""What the step screens use of the console app: its session, motion state, 3D view and
shared helpers. The app (:class:`spm_console.tui.app.SpmConsoleApp`) provides it; the
screens name only this protocol, so they never import the app that imports them."""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

from textual.screen import Screen

from spm_console.services.session import Session
from spm_console.store.form_memory import FormMemory
from spm_console.tui.switch import SwitchRequest
from spm_console.viewer.view import WristView


class ConsoleHost(Protocol):
    """The console app as the screens see it."""

    session: Session
    view: WristView
    moving: bool
    """A motion started from the console runs (the E-stop banner is up)."""
    viewer_url: str | None
    build_cancel: threading.Event | None
    """Set to cancel the workspace load or build under way (None: none runs)."""
    fk_done: bool
    form_memory: FormMemory
    live_samples: list[Any]
    profile_path: Path | None
    """The profile file in use (None: not from a file)."""
    stop_elsewhere: Callable[[str, bool], bool] | None
    """The E-stop of motions the session does not run (commissioning's own motion
    processes): called with the reason and whether a signal asked; None when none runs."""

    def cancel_build(self) -> bool: ...

    def telemetry_sink(self, screen: Screen[Any]) -> Callable[[Any], None]: ...

    def after_motion(self, result: Any) -> None: ...

    def restart_with(self, request: SwitchRequest | None) -> bool: ...
