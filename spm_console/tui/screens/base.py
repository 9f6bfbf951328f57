"""What every step screen shares: the step bar, E-stop banner, status line, footer, and
running blocking work in a thread worker that reports back by messages."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, ClassVar, cast

from textual import work
from textual.app import ComposeResult
from textual.screen import Screen
from textual.widgets import Footer
from textual.worker import get_current_worker

from spm_console.errors import SpmError
from spm_console.tui.messages import Done, Failed, Outcome
from spm_console.tui.widgets.estop import EstopBanner
from spm_console.tui.widgets.status import StatusLine
from spm_console.tui.widgets.steps import StepBar

if TYPE_CHECKING:
    from spm_console.run.operator import Session
    from spm_console.tui.app import SpmConsoleApp


def describe_error(exc: BaseException) -> str:
    """One readable line for the operator (never a traceback)."""
    if isinstance(exc, SpmError):
        return exc.message
    text = str(exc) or type(exc).__name__
    return f"internal error ({type(exc).__name__}): {text} — please report it"


class StepScreen(Screen[None]):
    """Base of the six step screens."""

    MODE: ClassVar[str] = ""
    AUTO_FOCUS = ""  # keys act on the screen until the operator tabs into a field (None = app default "*")

    def __init__(self) -> None:
        super().__init__()
        self.busy_op = ""

    @property
    def console(self) -> SpmConsoleApp:
        return cast("SpmConsoleApp", self.app)

    @property
    def session(self) -> Session:
        return self.console.session

    def compose(self) -> ComposeResult:
        yield StepBar(self.MODE)
        yield EstopBanner()
        yield from self.compose_body()
        yield StatusLine(id="status")
        yield Footer()

    def compose_body(self) -> ComposeResult:
        yield from ()

    @property
    def status(self) -> StatusLine:
        return self.query_one("#status", StatusLine)

    def on_screen_resume(self) -> None:
        self.refresh_view()

    def refresh_view(self) -> None:
        """Redraw from the session (called when the screen shows and after operations)."""
        self.query_one(StepBar).refresh_steps(self.session, self.console.fk_done,
                                              self.console.viewer_url)

    # ------------------------------------------------------------------ workers
    def run_blocking(self, op: str, fn: Callable[[], Outcome], busy_text: str) -> bool:
        """Run ``fn`` in a thread worker; its typed outcome comes back as Done, or Failed.

        Refused (returns False) while this screen is busy with another operation.
        """
        if self.busy_op:
            self.status.error(f"busy: {self.busy_op} is still running")
            return False
        self.busy_op = op
        self.status.busy(busy_text)
        self._worker(op, fn)
        return True

    @work(thread=True, exclusive=True, exit_on_error=False)
    def _worker(self, op: str, fn: Callable[[], Outcome]) -> None:
        try:
            result = fn()
        except BaseException as exc:  # every failure becomes a message, never a traceback
            if not get_current_worker().is_cancelled:
                self.post_message(Failed(op, describe_error(exc)))
            return
        if not get_current_worker().is_cancelled:
            self.post_message(Done(op, result))

    def on_done(self, message: Done) -> None:
        message.stop()
        self.busy_op = ""
        self.handle_done(message.outcome)
        self.refresh_view()

    def on_failed(self, message: Failed) -> None:
        message.stop()
        self.busy_op = ""
        self.status.error(message.message)
        self.notify(message.message, title="Error", severity="error", timeout=8, markup=False)
        self.handle_failed(message.op, message.message)
        self.refresh_view()

    def handle_done(self, outcome: Outcome) -> None:
        """Override: show what an operation produced (one dataclass per kind of outcome)."""

    def handle_failed(self, op: str, message: str) -> None:
        """Override: tidy up after ``op`` failed (the status line already says why)."""
