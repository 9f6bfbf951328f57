"""A file path asked for in a dialog (e.g. the saved plan to open): Enter accepts, esc cancels."""

from __future__ import annotations

from typing import ClassVar

from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Vertical
from textual.screen import ModalScreen
from textual.widgets import Input, Static

from spm_console.tui.widgets.field import TextField
from spm_console.tui.widgets.footer import ConsoleFooter

#: Longest path accepted, characters.
MAX_PATH = 1024


class AskPathScreen(ModalScreen[str | None]):
    """Dismisses with the typed path (as typed, stripped), or None."""

    BINDINGS: ClassVar[list[BindingType]] = [Binding("escape", "cancel", "Cancel")]

    def __init__(self, title: str, body: str, value: str = "") -> None:
        super().__init__()
        self._title, self._body, self._value = title, body, value

    def compose(self) -> ComposeResult:
        with Vertical(id="confirm-box"):
            yield Static(self._title, id="confirm-title", markup=False)
            yield Static(self._body, id="confirm-body", markup=False)
            yield TextField(value=self._value, id="ask-path", max_length=MAX_PATH)
        yield ConsoleFooter()

    def on_mount(self) -> None:
        self.query_one("#ask-path", Input).focus()

    def on_input_submitted(self, event: Input.Submitted) -> None:
        event.stop()
        self.dismiss(event.value.strip() or None)

    def action_cancel(self) -> None:
        self.dismiss(None)
