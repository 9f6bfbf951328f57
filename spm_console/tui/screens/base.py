"""What every step screen shares: the step bar, E-stop banner, status line, footer, the
keys that scroll and leave fields, and running blocking work in a thread worker that
reports back by messages.

Typing is never an action: while a text field or a dropdown has focus, a printable key
(letter, digit, '?', '.') goes to that widget and never reaches the screen's or the app's
bindings (step digits, single-letter actions). F-keys, ctrl+p and the E-stop still work.

The keys that move the focus (tab, shift+tab, esc) are priority bindings: they act when the
app reads them, before the keys behind them are handed to a widget. A burst of keys
(type-ahead, an unbracketed paste, tmux send-keys) "127.5 tab 83.2" then fills two fields
and "esc 6" leaves the field, then switches step; a non-priority binding runs only once the
key has bubbled up from the focused field, after the field took the keys queued behind it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import ClassVar, cast
from weakref import WeakSet

from textual import events, work
from textual.actions import SkipAction
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.dom import DOMNode
from textual.screen import Screen
from textual.widget import Widget
from textual.widgets import Footer, Input, Select, TextArea
from textual.worker import get_current_worker

from spm_console.errors import Issue, RefusedError, SolverError, SpmError
from spm_console.refusals import worded
from spm_console.services.session import Session
from spm_console.tui.host import ConsoleHost
from spm_console.tui.messages import Done, Failed, Outcome
from spm_console.tui.widgets.estop import ESTOP_KEY, EstopBanner
from spm_console.tui.widgets.footer import ConsoleFooter
from spm_console.tui.widgets.status import StatusLine
from spm_console.tui.widgets.steps import StepBar

#: The console's words after a runtime message (which names no console step or key), by
#: what went wrong.
CONSOLE_WORDS: dict[Issue, str] = {
    Issue.NOT_CONNECTED: " (step 1)",
    Issue.POSE_UNKNOWN: " (step 1)",
    Issue.NO_WORKSPACE: " (step 3)",
    Issue.NO_PLAN: " (step 4)",
    Issue.MOVING: " (press SPACE to stop it)",
}


def describe_error(exc: BaseException) -> str:
    """One readable line for the operator (never a traceback)."""
    if isinstance(exc, RefusedError):  # the motion process's refusal, in the console's words
        return worded(exc.reason, "console")
    if isinstance(exc, SpmError):
        return exc.message + (CONSOLE_WORDS.get(exc.issue, "") if exc.issue is not None else "")
    text = str(exc) or type(exc).__name__
    return f"internal error ({type(exc).__name__}): {text} — please report it"


#: Widgets that take typed characters: while one of them (or a widget inside one) has focus,
#: printable keys are typing, never actions.
TYPING_WIDGETS: tuple[type[Widget], ...] = (Input, TextArea, Select)

#: Terminals with fewer rows get one-line fields (app.tcss "Screen.-short" matches it).
COMPACT_BELOW_ROWS = 36
#: Terminals with fewer columns get a compact footer.
COMPACT_BELOW_COLUMNS = 100

_SCROLL = "Scroll"
_SCROLL_TIP = "the panel holding the focus, else the page (esc leaves a field first)"


def takes_typing(widget: DOMNode | None) -> bool:
    """True if ``widget`` or one of its ancestors is a text field, text area or dropdown."""
    node = widget
    while node is not None and not isinstance(node, Screen):
        if isinstance(node, TYPING_WIDGETS):
            return True
        node = node.parent
    return False


def _in_open_dropdown(widget: DOMNode | None) -> bool:
    """True inside a dropdown whose list is open."""
    node = widget
    while node is not None and not isinstance(node, Screen):
        if isinstance(node, Select):
            return bool(node.expanded)
        node = node.parent
    return False


class StepScreen(Screen[None]):
    """Base of the six step screens."""

    MODE: ClassVar[str] = ""
    AUTO_FOCUS = ""  # keys act on the screen until the operator tabs into a field (None = app default "*")
    BINDINGS: ClassVar[list[BindingType]] = [
        # First of every step screen's keys, so the footer shows it first while the wrist
        # moves (at 80 columns the keys after it are cut); shown and run only then (the
        # app's check_action), the app's own SPACE binding does the same.
        Binding(ESTOP_KEY, "app.estop", "E-STOP", priority=True, key_display="SPACE",
                system=True),
        Binding("escape", "leave_field", "Leave field", show=False, priority=True),
        Binding("tab", "move_focus('next')", "Focus Next", show=False, priority=True),
        Binding("shift+tab", "move_focus('previous')", "Focus Previous", show=False,
                priority=True),
        Binding("up", "scroll_panel('up')", _SCROLL, show=False, tooltip=_SCROLL_TIP),
        Binding("down", "scroll_panel('down')", _SCROLL, show=False, tooltip=_SCROLL_TIP),
        Binding("pageup", "scroll_panel('page_up')", _SCROLL, show=False, tooltip=_SCROLL_TIP,
                key_display="PgUp"),
        Binding("pagedown", "scroll_panel('page_down')", _SCROLL, show=False,
                tooltip=_SCROLL_TIP, key_display="PgDn"),
        Binding("home", "scroll_panel('home')", _SCROLL, show=False, tooltip=_SCROLL_TIP,
                key_display="Home"),
        Binding("end", "scroll_panel('end')", _SCROLL, show=False, tooltip=_SCROLL_TIP,
                key_display="End"),
    ]

    def __init__(self) -> None:
        super().__init__()
        # Textual re-parses every stylesheet of the app and restyles every widget, twice, on
        # the first visit of a mode whose screen has not seen the app's latest CSS update
        # (private to Textual 8). A new step's widgets are styled from the current stylesheet
        # as they mount, so the step starts up to date; a theme change restyles every screen
        # of the app, shown or not.
        self._css_update_count = self.app._css_update_count
        self.busy_op = ""
        self._made_compact: WeakSet[Widget] = WeakSet()

    @property
    def console(self) -> ConsoleHost:
        return cast("ConsoleHost", self.app)

    @property
    def session(self) -> Session:
        return self.console.session

    def compose(self) -> ComposeResult:
        yield StepBar(self.MODE)
        yield EstopBanner()
        yield from self.compose_body()
        yield StatusLine(id="status")
        yield ConsoleFooter()

    def compose_body(self) -> ComposeResult:
        yield from ()

    @property
    def status(self) -> StatusLine:
        return self.query_one("#status", StatusLine)

    def on_screen_resume(self) -> None:
        self.compact_fields()
        self.status.drop_refusal()
        self.status.drop_older_run(self.session.last_run)
        self.refresh_view()

    def on_resize(self) -> None:
        self.compact_fields()

    def compact_fields(self) -> None:
        """Below ``COMPACT_BELOW_ROWS`` rows, fields and dropdowns drop their borders (one
        line each, Textual's compact style), so forms fit 80×24; below
        ``COMPACT_BELOW_COLUMNS`` columns the footer drops its padding. Only widgets made
        compact here are restored when the terminal grows again."""
        short = self.size.height < COMPACT_BELOW_ROWS
        narrow = self.size.width < COMPACT_BELOW_COLUMNS
        for w in list(self.query("Input, Select, Footer").results()):  # one walk of the DOM
            if not isinstance(w, (Input, Select, Footer)):
                continue
            compact = narrow if isinstance(w, Footer) else short
            if compact and not w.compact:
                w.compact = True
                self._made_compact.add(w)
            elif not compact and w in self._made_compact:
                w.compact = False
                self._made_compact.discard(w)

    # ------------------------------------------------------------------ keys
    def on_key(self, event: events.Key) -> None:
        """A printable key typed while a field or dropdown has focus stays there: it never
        reaches a screen or app binding (bindings of the focused widget itself, such as a
        dropdown's space, still work). In a dropdown it goes nowhere: a bell says so."""
        if not event.is_printable or not takes_typing(self.focused):
            return
        bound = self.active_bindings.get(event.key)
        if bound is None or bound.node is self or bound.node is self.app:
            event.stop()
            event.prevent_default()
            if not isinstance(self.focused, (Input, TextArea)):
                self.app.bell()

    def action_leave_field(self) -> None:
        """Give the keys back to the screen (no widget focused). Outside a field, and in a
        dropdown whose list is open (its own esc closes the list), esc goes on as usual."""
        if not takes_typing(self.focused) or _in_open_dropdown(self.focused):
            raise SkipAction()
        self.set_focus(None)

    def action_move_focus(self, how: str) -> None:
        """tab (next) / shift+tab (previous): the focus moves before the next key is read."""
        if how == "previous":
            self.focus_previous()
        else:
            self.focus_next()

    def scroll_target(self) -> Widget | None:
        """What the scroll keys move: the nearest scrollable container around the focused
        widget, else the part of the screen with the most hidden content."""
        node: DOMNode | None = self.focused
        while isinstance(node, Widget) and node is not self:
            if node.allow_vertical_scroll and node.max_scroll_y > 0:
                return node
            node = node.parent
        candidates = [w for w in self.query(Widget)
                      if w.allow_vertical_scroll and w.max_scroll_y > 0]
        return max(candidates, key=lambda w: w.max_scroll_y, default=None)

    def action_scroll_panel(self, how: str) -> None:
        """Scroll :meth:`scroll_target` by a line (up / down), a page (page_up / page_down)
        or to its top / bottom (home / end)."""
        target = self.scroll_target()
        if target is None:
            raise SkipAction()
        if how == "up":
            target.scroll_up(animate=False)
        elif how == "down":
            target.scroll_down(animate=False)
        elif how == "page_up":
            target.scroll_page_up(animate=False)
        elif how == "page_down":
            target.scroll_page_down(animate=False)
        elif how == "home":
            target.scroll_home(animate=False)
        elif how == "end":
            target.scroll_end(animate=False)
        else:
            raise SkipAction()

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
                solver = isinstance(exc, SolverError) or not isinstance(exc, SpmError)
                issue = exc.issue if isinstance(exc, SpmError) else None
                self.post_message(Failed(op, describe_error(exc), solver, issue))
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
