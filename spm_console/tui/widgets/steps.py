"""The step bar on top of every screen: where you are, what is done, what to do next.

Each step has a function key (F10 for step 0, F1…F6, always), a digit (0…6, only while no text field or
dropdown has focus) and ctrl+digit where the terminal delivers it; the bar names the
F-keys and shortens its labels to fit the width (80 columns and up show every step).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from textual.app import ComposeResult
from textual.containers import Vertical
from textual.content import Content
from textual.widgets import Static

if TYPE_CHECKING:
    from spm_console.services.session import Session


@dataclass(frozen=True)
class Step:
    key: str
    """The digit key (and the number of the F-key)."""
    mode: str
    title: str
    short: str
    """The title at narrow widths."""

    @property
    def fnumber(self) -> str:
        """The function key's number: the digit's, F10 for step 0 (as on the keyboard's
        top row, where 0 follows 9)."""
        return "10" if self.key == "0" else self.key

    @property
    def fkey(self) -> str:
        """Textual's name of the function key ("f1" …)."""
        return f"f{self.fnumber}"

    @property
    def fkey_display(self) -> str:
        return f"F{self.fnumber}"


STEPS: tuple[Step, ...] = (
    Step("0", "commission", "Commission", "Commission"),
    Step("1", "connect", "Connect/home", "Connect"),
    Step("2", "fk", "FK check", "FK"),
    Step("3", "workspace", "Workspace", "Workspace"),
    Step("4", "plan", "Plan", "Plan"),
    Step("5", "execute", "Execute", "Execute"),
    Step("6", "logs", "Logs", "Logs"),
)
_BY_MODE = {s.mode: s for s in STEPS}


def keys_of(mode: str) -> str:
    """The keys of a step, for hint texts: "2 (F2)"."""
    s = _BY_MODE[mode]
    return f"{s.key} ({s.fkey_display})"


def press(mode: str) -> str:
    """"press 2 (F2)"."""
    return f"press {keys_of(mode)}"


def done_steps(session: Session) -> set[str]:
    done = set()
    if session.homed:
        done.add("connect")
    if session.wrist.workspace is not None:
        done.add("workspace")
    if session.plans.plan is not None:
        done.add("plan")
    if session.plans.plan is not None and session.plans.info is not None and session.plans.info.executed_ok:
        done.add("execute")  # a stopped run of the plan is no tick
    return done


#: What to do on a step to get its work done: the hint says this on that step itself
#: ("press 2 (F2) for an FK check" read oddly on step 2).
HERE = {
    "commission": "type the ports and press s to commission the wrist",
    "fk": "type θ and press f for an FK check",
    "workspace": "press l to load the workspace",
    "plan": "choose start and goal, then press s to plan a motion",
    "execute": "press x to execute the plan",
    "logs": "pick a run and press Enter to look at its log",
}


def next_hint(session: Session, fk_done: bool = False, current: str = "") -> str:
    """The obvious next step, as one sentence with its key (on the ``current`` step: what to
    do there)."""
    def act(mode: str, what: str) -> str:
        return HERE[mode] if mode == current else f"{press(mode)}{what}"

    def alt(mode: str, what: str) -> str:  # the second choice of a hint
        return HERE[mode] if mode == current else f"{keys_of(mode)}{what}"

    if session.moving.is_set():
        return "The wrist is moving: SPACE stops it."
    if session.bus is None:
        return "Next: press c to connect to the servos."
    if not session.homed:
        return "Next: press h to home the wrist."
    if not fk_done and session.wrist.workspace is None:
        return f"Next: {act('fk', ' for an FK check')}, or {alt('workspace', ' for the workspace')}."
    if session.wrist.workspace is None:
        return f"Next: {act('workspace', ' to load the workspace')}."
    if session.plans.plan is None and not fk_done:
        return (f"Next: {act('fk', ' for an FK check')}, or "
                f"{alt('plan', ' to plan a motion (s solves)')}.")
    if session.plans.plan is None:
        return f"Next: {act('plan', ' to plan a motion (s solves)')}."
    run = session.last_run
    if run is None or session.plans.info is None or not session.plans.info.executed:
        return f"Next: {act('execute', ', then x to execute the plan')}."
    return f"Next: {act('logs', ' to look at the run log')}, or {alt('plan', ' to plan another')}."


def step_labels(current: str, done: set[str], width: int) -> Content:
    """The steps in one line of at most ``width`` cells: full titles if they fit, else short
    ones; else step 0 (commissioning, once per wrist) by its key alone, else left out (unless
    current), so that the six operating steps keep their titles at 80 columns; else only the
    keys (and the current step's short title)."""
    zero = STEPS[0].mode

    def line(title_of: dict[str, str], steps: tuple[Step, ...] = STEPS) -> Content:
        parts = []
        for s in steps:
            title = title_of.get(s.mode, "")
            mark = "✔" if s.mode in done else ""
            text = " ".join(p for p in (s.fkey_display, mark, title) if p)
            text = f" {text} "
            if s.mode == current:
                parts.append(Content.styled(text, "bold reverse"))
            elif s.mode in done:
                parts.append(Content.styled(text, "green"))
            else:
                parts.append(Content(text))
        return Content("│").join(parts)

    short = {s.mode: s.short for s in STEPS}
    untitled_zero = {m: t for m, t in short.items() if m != zero}
    candidates = (
        line({s.mode: s.title for s in STEPS}),
        line(short),
        line(untitled_zero),
        line(untitled_zero, tuple(s for s in STEPS if s.mode != zero or s.mode == current)),
    )
    for out in candidates:
        if out.cell_length <= width:
            return out
    return line({current: _BY_MODE[current].short} if current in _BY_MODE else {})


class StepBar(Vertical):
    """The steps (current one highlighted, done ones ticked), the hint, the 3D view URL."""

    DEFAULT_CLASSES = "step-bar"

    def __init__(self, current: str) -> None:
        super().__init__()
        self.current = current
        self._done: set[str] = set()

    def compose(self) -> ComposeResult:
        yield Static(id="steps-line")
        yield Static(id="hint-line", markup=False)
        yield Static(id="view-line", markup=False)

    def on_resize(self) -> None:
        self._draw_steps()

    def _draw_steps(self) -> None:
        width = self.content_size.width or self.app.size.width
        self.query_one("#steps-line", Static).update(step_labels(self.current, self._done, width))

    def refresh_steps(self, session: Session, fk_done: bool, viewer_url: str | None) -> None:
        done = done_steps(session)
        if fk_done:
            done.add("fk")
        self._done = done
        self._draw_steps()
        view = self.query_one("#view-line", Static)
        view.display = bool(viewer_url)
        view.update(Content.styled(f" 3D view: {viewer_url} (open it in a browser)", "cyan"))
        self.query_one("#hint-line", Static).update(
            Content(next_hint(session, fk_done, self.current)))
