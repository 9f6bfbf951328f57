"""The large E-stop banner shown on every screen while the wrist moves."""

from __future__ import annotations

from textual.content import Content
from textual.widgets import Static

ESTOP_KEY = "space"
"""The single key that stops any motion (an app-level priority binding)."""


class EstopBanner(Static):
    """Hidden unless the app's ``moving`` flag is set."""

    DEFAULT_CLASSES = "estop-banner"

    def on_mount(self) -> None:
        self.update(Content("■■  E-STOP: press SPACE to stop the wrist now  ■■"))
        self.watch(self.app, "moving", self._moving_changed, init=True)

    def _moving_changed(self, moving: bool) -> None:
        self.display = bool(moving)
