"""The step bar on top of every screen: where you are, what is done, what to do next."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from textual.app import ComposeResult
from textual.containers import Vertical
from textual.content import Content
from textual.widgets import Static

if TYPE_CHECKING:
    from spm_console.run.operator import Session


@dataclass(frozen=True)
class Step:
    key: str
    mode: str
    title: str


STEPS: tuple[Step, ...] = (
    Step("1", "connect", "Connect/home"),
    Step("2", "fk", "FK check"),
    Step("3", "workspace", "Workspace"),
    Step("4", "plan", "Plan"),
    Step("5", "execute", "Execute"),
    Step("6", "logs", "Logs"),
)


def done_steps(session: Session) -> set[str]:
    done = set()
    if session.homed:
        done.add("connect")
    if session.workspace is not None:
        done.add("workspace")
    if session.plan is not None:
        done.add("plan")
    if session.plan is not None and session.plan_info.get("executed"):
        done.add("execute")
    return done


def next_hint(session: Session, fk_done: bool = False) -> str:
    """The obvious next step, as one sentence with its key."""
    if session.moving.is_set():
        return "The wrist is moving: SPACE stops it."
    if session.bus is None:
        return "Next: press c to connect to the servos."
    if not session.homed:
        return "Next: press h to home the wrist."
    if not fk_done and session.workspace is None:
        return "Next: press 2 for an FK check (or 3 for the workspace)."
    if session.workspace is None:
        return "Next: press 3 to load the workspace."
    if session.plan is None and not fk_done:
        return "Next: press 2 for an FK check, or 4 to plan a motion (s solves)."
    if session.plan is None:
        return "Next: press 4 to plan a motion (s solves)."
    run = session.last_run
    if run is None or session.plan_info.get("executed") is not True:
        return "Next: press 5, then x to execute the plan."
    return "Next: press 6 to look at the run log (or 4 to plan another motion)."


class StepBar(Vertical):
    """Two lines: the six steps (current one highlighted, done ones ticked) and the hint."""

    DEFAULT_CLASSES = "step-bar"

    def __init__(self, current: str) -> None:
        super().__init__()
        self.current = current

    def compose(self) -> ComposeResult:
        yield Static(id="steps-line")
        yield Static(id="hint-line", markup=False)
        yield Static(id="view-line", markup=False)

    def refresh_steps(self, session: Session, fk_done: bool, viewer_url: str | None) -> None:
        done = done_steps(session)
        if fk_done:
            done.add("fk")
        parts = []
        for s in STEPS:
            mark = "✔ " if s.mode in done else ""
            text = f" {s.key} {mark}{s.title} "
            if s.mode == self.current:
                parts.append(Content.styled(text, "bold reverse"))
            elif s.mode in done:
                parts.append(Content.styled(text, "green"))
            else:
                parts.append(Content(text))
            parts.append(Content("│"))
        self.query_one("#steps-line", Static).update(Content("").join(parts[:-1]))
        view = self.query_one("#view-line", Static)
        view.display = bool(viewer_url)
        view.update(Content.styled(f" 3D view: {viewer_url} (open it in a browser)", "cyan"))
        self.query_one("#hint-line", Static).update(Content(next_hint(session, fk_done)))
