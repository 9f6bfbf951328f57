"""Yes/no confirmation before anything that moves the wrist or discards work."""

from __future__ import annotations

from typing import ClassVar

from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Button, Static

from spm_console.tui.widgets.footer import ConsoleFooter


class ConfirmScreen(ModalScreen[bool]):
    """Dismisses with True on 'y' / Yes, False on 'n', escape / No."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("y", "answer(True)", "Yes"),
        Binding("n", "answer(False)", "No"),
        Binding("escape", "answer(False)", "Cancel"),
    ]

    def __init__(self, title: str, body: str, yes: str = "Yes (y)", no: str = "No (n)") -> None:
        super().__init__()
        self._title = title
        self._body = body
        self._yes = yes
        self._no = no

    def compose(self) -> ComposeResult:
        with Vertical(id="confirm-box"):
            yield Static(self._title, id="confirm-title", markup=False)
            yield Static(self._body, id="confirm-body", markup=False)
            with Horizontal(id="confirm-buttons"):
                yield Button(self._yes, id="yes", variant="warning")
                yield Button(self._no, id="no", variant="primary")
        yield ConsoleFooter()

    def on_mount(self) -> None:
        self.query_one("#no", Button).focus()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        event.stop()
        self.dismiss(event.button.id == "yes")

    def action_answer(self, yes: bool) -> None:
        self.dismiss(yes)


class QuitConfirm(ConfirmScreen):
    """Asked on q (or ctrl+q): q again or y quits, n or esc stays (the footer says so)."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("q,y", "answer(True)", "Quit", key_display="q/y"),
        Binding("n", "answer(False)", "Stay"),
        Binding("escape", "answer(False)", "Stay", show=False),
    ]

    def __init__(self) -> None:
        super().__init__(
            "Quit the console?",
            "The session closes: the servos' bus is disconnected, a workspace build under way "
            "is cancelled and the 3D view stops.\nPress q again or y to quit, n or esc to "
            "stay.", yes="Quit (q, y)", no="Stay (n)")
