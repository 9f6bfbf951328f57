"""The one-line status of a screen: what is happening, what went wrong (as plain text)."""

from __future__ import annotations

from textual.content import Content
from textual.widgets import Static


class StatusLine(Static):
    """Plain text (never parsed as markup, so '[...]' in messages shows as typed)."""

    DEFAULT_CLASSES = "status-line"

    _refusal = False

    def _show(self, text: str, cls: str) -> None:
        self._refusal = False
        self.remove_class("-ok", "-error", "-busy")
        self.add_class(cls)
        self.update(Content(text))

    def ok(self, text: str) -> None:
        self._show(text, "-ok")

    def error(self, text: str) -> None:
        self._show(text, "-error")

    def refused(self, text: str) -> None:
        """An action refused for the state of the session (no plan yet, not homed): shown as
        an error until :meth:`drop_refusal`, as the state may have changed since."""
        self._show(text, "-error")
        self._refusal = True

    def drop_refusal(self) -> None:
        """Clear the line if it shows a refusal (the screen shows again: the state it was
        about may have changed)."""
        if self._refusal:
            self._show("", "-ok")

    def busy(self, text: str) -> None:
        self._show(text, "-busy")

    @property
    def text(self) -> str:
        return str(self.render())
