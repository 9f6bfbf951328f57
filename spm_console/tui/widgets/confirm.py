"""Yes/no confirmation before anything that moves the wrist or discards work."""

from __future__ import annotations

from typing import ClassVar

from textual import events
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal, Vertical, VerticalScroll
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
            yield from self.compose_body()
            with Horizontal(id="confirm-buttons"):
                yield Button(self._yes, id="yes", variant="warning")
                yield Button(self._no, id="no", variant="primary")
        yield ConsoleFooter()

    def compose_body(self) -> ComposeResult:
        """The question's text, between the title and the buttons."""
        yield Static(self._body, id="confirm-body", markup=False)

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


#: Rows of a confirmation besides its body (border, padding, title, buttons, the footer).
CONFIRM_FRAME_ROWS = 11


class LongConfirm(ConfirmScreen):
    """A confirmation whose body may be longer than the terminal: as wide as 100 columns
    (the terminal's width below that), the body wrapped there and scrolled by ↑ ↓ PgUp PgDn
    Home End while the buttons stay in view."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("up", "scroll_body('up')", "Scroll", show=False),
        Binding("down", "scroll_body('down')", "Scroll", show=False),
        Binding("pageup", "scroll_body('page_up')", "Scroll", show=False),
        Binding("pagedown", "scroll_body('page_down')", "Scroll", show=False),
        Binding("home", "scroll_body('home')", "Scroll", show=False),
        Binding("end", "scroll_body('end')", "Scroll", show=False),
    ]

    def compose_body(self) -> ComposeResult:
        with VerticalScroll(id="confirm-scroll"):
            yield Static(self._body, id="confirm-body", markup=False)

    def on_mount(self) -> None:
        super().on_mount()
        self._fit()

    def on_resize(self, event: events.Resize) -> None:
        self._fit()

    def _fit(self) -> None:
        """The body's scroll as high as the terminal leaves beside the rest."""
        self.query_one("#confirm-scroll").styles.max_height = max(
            3, self.size.height - CONFIRM_FRAME_ROWS)

    def action_scroll_body(self, how: str) -> None:
        scroll = self.query_one("#confirm-scroll", VerticalScroll)
        getattr(scroll, f"scroll_{how}")(animate=False)
