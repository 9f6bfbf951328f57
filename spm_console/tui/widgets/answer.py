"""A question with a few allowed answers, asked from a worker thread (commissioning without an
IMU: "which leg's arm moved?"), and the modal that shows it: one button per answer, each with
its key.

:func:`asker` makes the ``Ask`` of
:mod:`spm_console.services.commissioning.stages` for the console: the worker blocks until the
operator answers, at most :data:`~spm_console.services.commissioning.stages.ANSWER_TIMEOUT_S`;
an E-stop (SPACE, a signal) while the question is open closes it and ends the stage, as esc
does."""

from __future__ import annotations

import contextlib
import queue
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

from textual import events
from textual.app import App, ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal, Vertical
from textual.screen import ModalScreen
from textual.widgets import Button, Static

from spm_console.errors import BadInputError
from spm_console.tui.widgets.footer import ConsoleFooter

if TYPE_CHECKING:
    from spm_console.services.client import EstopRelay

#: How often the waiting worker looks at the E-stop, s.
POLL_S = 0.1


def answer_keys(answers: Sequence[str]) -> tuple[str, ...]:
    """The key of each answer: the answer itself when it is one character, else its first
    letter when no other answer starts with it, else its place in the list (1, 2, …)."""
    firsts = [a[:1].lower() for a in answers]
    keys = []
    for k, a in enumerate(answers):
        if len(a) == 1 and a.isalnum():
            keys.append(a.lower())
        elif firsts[k].isalpha() and firsts.count(firsts[k]) == 1:
            keys.append(firsts[k])
        else:
            keys.append(str(k + 1))
    if len(set(keys)) != len(keys):  # e.g. an answer "2" beside a second answer keyed 2
        return tuple(str(k + 1) for k in range(len(answers)))
    return tuple(keys)


class AnswerScreen(ModalScreen[str | None]):
    """Dismisses with the answer chosen (its key or its button), None on esc."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("escape", "dismiss_none", "Give up", tooltip="no answer: the stage ends"),
    ]

    def __init__(self, title: str, question: str, answers: Sequence[str]) -> None:
        super().__init__()
        self._title = title
        self.question = question
        self.answers = tuple(answers)
        self.keys = answer_keys(self.answers)

    def compose(self) -> ComposeResult:
        with Vertical(id="confirm-box"):
            yield Static(self._title, id="confirm-title", markup=False)
            yield Static(self.question, id="answer-question", markup=False)
            with Horizontal(id="confirm-buttons"):
                for k, (a, key) in enumerate(zip(self.answers, self.keys, strict=True)):
                    yield Button(f"{a} ({key})", id=f"answer-{k}", variant="primary")
            yield Static("Press an answer's key (or tab to its button, enter); esc gives up "
                         "(the stage ends); SPACE stops the wrist.", id="answer-help",
                         markup=False)
        yield ConsoleFooter()

    def on_key(self, event: events.Key) -> None:
        key = (event.character or "").lower()
        if key and key in self.keys:
            event.stop()
            self.dismiss(self.answers[self.keys.index(key)])

    def on_button_pressed(self, event: Button.Pressed) -> None:
        event.stop()
        self.dismiss(self.answers[int(str(event.button.id).removeprefix("answer-"))])

    def action_dismiss_none(self) -> None:
        self.dismiss(None)


def asker(app: App[Any], stop: EstopRelay, title: str,
          timeout_s: float) -> Callable[[str, Sequence[str]], str]:
    """The operator asked in ``app`` from a worker thread (see the module docstring)."""

    def ask(question: str, answers: Sequence[str]) -> str:
        stop.check()
        box: queue.Queue[str | None] = queue.Queue(1)
        screen = AnswerScreen(title, question, answers)
        app.call_from_thread(app.push_screen, screen, box.put)
        t_end = time.monotonic() + timeout_s
        try:
            while True:
                try:
                    answer = box.get(timeout=POLL_S)
                    break
                except queue.Empty:
                    pass
                stop.check()
                if time.monotonic() >= t_end:
                    raise BadInputError(f"{stop.what}: no answer within {timeout_s:g} s to "
                                        f"{question!r}")
        finally:
            with contextlib.suppress(RuntimeError):  # the console ended (a signal): no dialog
                app.call_from_thread(_close, app, screen)
        if answer is None:
            raise BadInputError(f"{stop.what}: no answer to {question!r} (esc)")
        return answer

    return ask


def _close(app: App[Any], screen: AnswerScreen) -> None:
    """Dismiss ``screen`` if it is still the one on top (the worker gave up waiting)."""
    if app.screen is screen:
        screen.dismiss(None)
