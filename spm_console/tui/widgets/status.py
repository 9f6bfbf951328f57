"""The one-line status of a screen: what is happening, what went wrong (as plain text)."""

from __future__ import annotations

from typing import Any

from textual.content import Content
from textual.widgets import Static


class StatusLine(Static):
    """Plain text (never parsed as markup, so '[...]' in messages shows as typed)."""

    DEFAULT_CLASSES = "status-line"

    _refusal = False
    _run: Any = None

    def _show(self, text: str, cls: str) -> None:
        self._refusal = False
        self._run = None
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

    def run_result(self, text: str, run: Any) -> None:
        """The outcome of ``run`` (ok or not, by ``run.ok``), shown until a later run ends:
        see :meth:`drop_older_run`."""
        self._show(text, "-ok" if run.ok else "-error")
        self._run = run

    def drop_older_run(self, last_run: Any) -> None:
        """Clear the line if it tells of a run other than ``last_run`` (a later run ended,
        on another step: this line would show an old outcome as the current one)."""
        if self._run is not None and self._run is not last_run:
            self._show("", "-ok")

    def busy(self, text: str) -> None:
        self._show(text, "-busy")

    @property
    def text(self) -> str:
        return str(self.render())
