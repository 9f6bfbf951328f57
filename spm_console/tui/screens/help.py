"""The keys of the current screen and the global ones, generated from the bindings (so the
list cannot drift from what the keys do): the help screen (`?`) and the command palette's
entries (ctrl+p) both come from :func:`key_entries`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

from rich.console import Group
from rich.table import Table
from rich.text import Text
from textual.actions import ActionError, parse
from textual.app import ComposeResult
from textual.binding import Binding, BindingsMap, BindingType
from textual.containers import Vertical, VerticalScroll
from textual.content import Content
from textual.dom import DOMNode
from textual.screen import ModalScreen, Screen
from textual.widgets import Static

from spm_console.tui.widgets.footer import ConsoleFooter
from spm_console.tui.widgets.steps import STEPS

if TYPE_CHECKING:
    from textual.app import App

#: Smallest width of the keys column, cells.
KEYS_WIDTH = 10
#: An action's name is padded to this width before its note, cells.
ACTION_WIDTH = 16

TYPING_RULE = (
    "While a text field or a dropdown has focus, letters, digits and '?' go to it and never "
    "act: F10 and F1…F6 switch steps, ctrl+p opens the palette, ctrl+o or F7 the settings (profile, "
    "grid step), esc leaves the field, and SPACE stops the wrist while it moves. Outside "
    "fields the digits 0…6 switch steps too."
)


@dataclass(frozen=True)
class KeyEntry:
    """One action and every key bound to it on one node (the screen or the app)."""

    keys: tuple[str, ...]
    """Display forms, in binding order ("F4", "4", "^4")."""
    description: str
    action: str
    """The action string of the first binding (what the palette runs)."""
    single_action: bool
    """All keys run the same action (the scroll keys, for example, do not)."""
    node: DOMNode
    """Where the action runs: the screen or the app."""
    state: bool | None
    """The node's check_action now: True available, None shown but not now, False hidden."""
    tooltip: str = ""

    @property
    def keys_text(self) -> str:
        return " ".join(self.keys)


def action_state(node: DOMNode, action: str) -> bool | None:
    """``check_action`` of the node an action string addresses ("app.x" runs on the app)."""
    try:
        prefix, name, params = parse(action)
    except ActionError:
        return False
    target: DOMNode = node
    if prefix == "app":
        target = node.app
    elif prefix == "screen":
        target = node.screen
    return target.check_action(name, params)


def _rank(node: DOMNode, binding: Binding) -> int:
    """How far up the node's class hierarchy the binding is declared (0: the node's own
    class), so a screen's own keys list before the inherited ones."""
    mro = type(node).__mro__
    for i, cls in enumerate(mro):
        for b in cls.__dict__.get("BINDINGS", ()):
            keys, action = (b.key, b.action) if isinstance(b, Binding) else (b[0], b[1])
            if action == binding.action and binding.key in keys.split(","):
                return i
    return len(mro)


def _bindings(node: DOMNode) -> list[Binding]:
    # The node's merged bindings (class BINDINGS along the MRO, keymap applied), own first.
    found = [b for _key, b in node._bindings if not b.system]
    return sorted(found, key=lambda b: _rank(node, b))


def key_entries(screen: Screen[Any], app: App[Any]) -> list[tuple[DOMNode, list[KeyEntry]]]:
    """The screen's entries, then the app's: keys bound to the same description on the same
    node form one entry (F4 / 4 / ctrl+4, or the six scroll keys)."""
    out: list[tuple[DOMNode, list[KeyEntry]]] = []
    for node in (screen, app):
        groups: dict[str, list[Binding]] = {}
        for b in _bindings(node):
            desc = b.description or b.action.replace("_", " ")
            groups.setdefault(desc, []).append(b)
        entries = []
        for desc, bs in groups.items():
            keys = tuple(dict.fromkeys(app.get_key_display(b) for b in bs))
            actions = {b.action for b in bs}
            tooltip = next((b.tooltip for b in bs if b.tooltip), "")
            entries.append(KeyEntry(keys, desc, bs[0].action, len(actions) == 1, node,
                                    action_state(node, bs[0].action), tooltip))
        out.append((node, entries))
    return out


#: Actions that move the focus, not operations of a step (left out of :func:`step_actions`).
_NAVIGATION = ("leave_field", "move_focus")


def step_actions(screen_class: type[Screen[Any]], app: App[Any]) -> list[KeyEntry]:
    """The actions a step screen's class declares itself (its operations, not the keys it
    inherits such as scrolling), one entry per description, for a screen that may not
    exist yet; ``state`` is None (unknown until the step shows)."""
    groups: dict[str, list[Binding]] = {}
    for _key, b in BindingsMap(screen_class.__dict__.get("BINDINGS", ())):
        if b.system or b.action.partition("(")[0] in _NAVIGATION:
            continue
        groups.setdefault(b.description or b.action.replace("_", " "), []).append(b)
    return [KeyEntry(tuple(dict.fromkeys(app.get_key_display(b) for b in bs)), desc,
                     bs[0].action, len({b.action for b in bs}) == 1, app, None,
                     next((b.tooltip for b in bs if b.tooltip), ""))
            for desc, bs in groups.items() if len({b.action for b in bs}) == 1]


def screen_title(screen: Screen[Any]) -> str:
    """"Plan (step 4)" for a step screen (its ``HELP_TITLE`` when it has one), else the
    screen's class name in words."""

    title = getattr(screen, "HELP_TITLE", "")
    if title:
        return str(title)

    mode = getattr(screen, "MODE", "")
    for s in STEPS:
        if s.mode == mode:
            return f"{s.title} (step {s.key})"
    return type(screen).__name__.removesuffix("Screen") or "this screen"


def help_table(screen: Screen[Any], app: App[Any]) -> Group:
    """Two sections (this screen, everywhere), one row per action: keys, name, note; the
    screen's ``HELP_NOTE`` when it has one; then the typing rule."""
    parts: list[Any] = []
    sections = key_entries(screen, app)
    keys_width = max([KEYS_WIDTH] + [len(e.keys_text) for _n, es in sections for e in es])
    for node, entries in sections:
        head = f"On this step: {screen_title(screen)}" if node is screen else "Everywhere"
        parts.append(Text(head, style="bold underline"))
        # keys, then the action and its note in one column that wraps: at 80 columns a
        # third column for the notes was left about 10 cells wide
        table = Table.grid(padding=(0, 2), expand=True)
        table.add_column(no_wrap=True, style="bold", min_width=keys_width)
        table.add_column(ratio=1)
        for e in entries:
            note = e.tooltip
            if e.state is None:
                note = "not now" + (f": {note}" if note else "")
            elif e.state is False:
                note = note or "not available now"
            what = Text(e.description.ljust(ACTION_WIDTH) if note else e.description)
            if note:
                what.append(f"  {note}", style="dim")
            table.add_row(e.keys_text, what)
        parts += [table, Text("")]
        note = getattr(screen, "HELP_NOTE", "")
        if node is screen and note:
            parts += [Text(str(note)), Text("")]
    parts += [Text("Typing", style="bold underline"), Text(TYPING_RULE)]
    return Group(*parts)


class HelpScreen(ModalScreen[None]):
    """Every key of the screen below and of the app; esc or ? closes it."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("escape", "close", "Close"),
        Binding("question_mark", "close", "Close", key_display="?"),
    ]

    def __init__(self, under: Screen[Any]) -> None:
        super().__init__()
        self.under = under

    def compose(self) -> ComposeResult:
        with Vertical(id="help-box"):
            yield Static(Content.styled("Keys (esc or ? closes; ↑ ↓ PgUp PgDn scroll)", "bold"),
                         id="help-title")
            with VerticalScroll(id="help-scroll"):
                yield Static(help_table(self.under, self.app), id="help-text")
        yield ConsoleFooter()

    def on_mount(self) -> None:
        self.query_one("#help-scroll", VerticalScroll).focus()

    def action_close(self) -> None:
        self.dismiss(None)
