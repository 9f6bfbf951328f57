"""The one-line status of a screen: what is happening, what went wrong (as plain text)."""

from __future__ import annotations

from textual.content import Content
from textual.widgets import Static


class StatusLine(Static):
    """Plain text (never parsed as markup, so '[...]' in messages shows as typed)."""

    DEFAULT_CLASSES = "status-line"

    def _show(self, text: str, cls: str) -> None:
        self.remove_class("-ok", "-error", "-busy")
        self.add_class(cls)
        self.update(Content(text))

    def ok(self, text: str) -> None:
        self._show(text, "-ok")

    def error(self, text: str) -> None:
        self._show(text, "-error")

    def busy(self, text: str) -> None:
        self._show(text, "-busy")

    @property
    def text(self) -> str:
        return str(self.render())
