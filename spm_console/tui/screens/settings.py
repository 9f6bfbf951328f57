"""Settings (ctrl+o or F7): the profile and the workspace grid step Δ of the console.

Both shape everything the runtime does (the workspace, the certified set every plan is
verified against, the motion process, the 3D view), so applying them restarts the
console: this dialog dismisses with a :class:`SwitchRequest`, the app closes its session
(E-stop, motion process, viewer) and exits with it, and ``spm-console tui`` starts a new
console for the new profile and grid step in the same terminal. Refused while the wrist
moves; the grid step is checked as typed (never altered) and the whole profile is validated
before the confirmation.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar, cast

from textual import events, work
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal, VerticalScroll
from textual.content import Content
from textual.screen import ModalScreen
from textual.widgets import Button, Input, Label, OptionList, Static
from textual.widgets.option_list import Option

from spm_console.config.checks import grid_step_problems
from spm_console.config.load import MAX_PROFILE_BYTES, load_profile, with_grid_step
from spm_console.config.schema import DEFAULT_PROFILE
from spm_console.errors import BadInputError, SpmError
from spm_console.safe_io import FileRefusedError, read_capped
from spm_console.store.identified_profiles import FitFigures, arrange, family, fit_figures
from spm_console.tui.host import ConsoleHost
from spm_console.tui.switch import SwitchRequest
from spm_console.tui.widgets.confirm import ConfirmScreen
from spm_console.tui.widgets.footer import ConsoleFooter
from spm_console.tui.widgets.number import NumberRow, NumberRule

#: Largest grid step accepted, deg (as ``spm-console tui --grid-step``).
GRID_STEP_MAX_DEG = 30.0
#: Below this many rows the grid-step field is one line (as the step screens' fields).
COMPACT_BELOW_ROWS = 36


def grid_step_rule() -> NumberRule:
    """Δ in (0, GRID_STEP_MAX_DEG] deg; the profile check then asks for a whole number of
    steps across the grid range and applies the node cap."""
    return NumberRule("grid step Δ", "a step in degrees", "°", 0.0, GRID_STEP_MAX_DEG,
                      lo_open=True)


@dataclass(frozen=True)
class ProfileEntry:
    """One profile file as listed: its name and own grid step from the file, or why it
    cannot be read (then it cannot be chosen)."""

    path: Path
    name: str = ""
    step_deg: float | None = None
    """The profile's own workspace.step_deg, deg (None when unreadable)."""
    error: str = ""
    range_deg: tuple[float, float] | None = None
    """Its workspace.theta_min_deg, theta_max_deg (None when unreadable): a typed grid step
    is checked against this range at once (whole steps, node cap)."""
    fit: FitFigures | None = None
    """Its identified servo model's figures (None: not identified)."""

    def label(self) -> str:
        if self.error:
            return f"{self.path}: {self.error}"
        own = "" if self.step_deg is None else f"   (its grid step {self.step_deg:g}°)"
        fit = "" if self.fit is None else f"\n    {self.fit.words()}"
        return f"{self.name}   {self.path}{own}{fit}"


def profile_dirs() -> list[Path]:
    """The ``profiles/`` folders to list: the one beside the working directory (where the
    default profile lives) and the one of the source tree, when they exist."""
    here = DEFAULT_PROFILE.parent
    tree = Path(__file__).resolve().parents[3] / "profiles"
    out: list[Path] = []
    for d in (here, tree):
        if d.is_dir() and all(d.resolve() != o.resolve() for o in out):
            out.append(d)
    return out


def read_entry(path: Path) -> ProfileEntry:
    """Name and grid step of a profile file, from its TOML (quick; Apply validates it all)."""
    try:
        data = tomllib.loads(read_capped(path, MAX_PROFILE_BYTES).decode("utf-8"))
        name = data["profile"]["name"]
        step = float(data["workspace"]["step_deg"])
    except FileRefusedError as exc:
        return ProfileEntry(path, error=exc.reason)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError):
        return ProfileEntry(path, error="not valid TOML")
    except (KeyError, TypeError, ValueError):
        return ProfileEntry(path, error="not a profile (no profile.name / workspace.step_deg)")
    if not isinstance(name, str) or not math.isfinite(step):
        return ProfileEntry(path, error="not a profile (bad profile.name / workspace.step_deg)")
    try:
        lo, hi = (float(data["workspace"][k]) for k in ("theta_min_deg", "theta_max_deg"))
        rng = (lo, hi) if math.isfinite(lo) and math.isfinite(hi) else None
    except (KeyError, TypeError, ValueError):
        rng = None  # Apply's whole-profile check says what is wrong
    return ProfileEntry(path, name, step, range_deg=rng, fit=fit_figures(data))


def list_profiles(current: Path | None, dirs: Iterable[Path] | None = None) -> list[ProfileEntry]:
    """Every ``*.toml`` of the profile folders (sorted), then ``current`` with its family
    (its base profile and their identified profiles) if it lives elsewhere; each base
    profile followed by its identified profiles, newest first
    (:func:`~spm_console.store.identified_profiles.arrange`)."""
    paths: list[Path] = []
    for d in profile_dirs() if dirs is None else dirs:
        paths += sorted(d.glob("*.toml"))
    if current is not None:
        paths += [current, *family(current)]
    return [read_entry(p) for p in arrange(paths)]


class SettingsScreen(ModalScreen[SwitchRequest | None]):
    """Pick a profile (Enter moves on to the grid step) and type a grid step; Apply (a
    outside the field, ctrl+s, Enter in the field) checks both, asks, and dismisses with a
    :class:`SwitchRequest`; esc closes without a change."""

    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("escape", "cancel", "Close"),
        Binding("a", "apply", "Apply", tooltip="restarts the console (asks first)"),
        Binding("ctrl+s", "apply", "Apply", tooltip="restarts the console (asks first)"),
    ]
    DEFAULT_CSS = """
    SettingsScreen { align: center middle; }
    #settings-box {
        width: 90; max-width: 100%; height: auto; max-height: 100%;
        border: thick $primary; background: $surface; padding: 0 1;
    }
    #settings-title { text-style: bold; }
    #settings-profiles { height: auto; max-height: 10; }
    #settings-reason { color: $error; text-style: bold; height: auto; }
    #settings-buttons { height: 3; align: center middle; }
    #settings-buttons Button { margin: 0 2; }
    """

    def __init__(self, current: Path | None, profile_name: str, grid_step_deg: float,
                 entries: list[ProfileEntry] | None = None) -> None:
        super().__init__()
        self.current = current
        self.profile_name = profile_name
        self.grid_step_deg = grid_step_deg
        self.entries = list_profiles(current) if entries is None else entries
        self.checking = False

    @property
    def console(self) -> ConsoleHost:
        return cast("ConsoleHost", self.app)

    def compose(self) -> ComposeResult:
        where = "" if self.current is None else f" ({self.current})"
        with VerticalScroll(id="settings-box"):
            yield Static(Content("Settings: profile and workspace grid step"),
                         id="settings-title")
            yield Static(Content(
                f"In use: profile {self.profile_name}{where}, grid step "
                f"{self.grid_step_deg:g}°. Applying restarts the console (motion process, "
                "workspace, 3D view) at the connect step."), id="settings-now")
            yield Label("Profile (↑ ↓ choose)", markup=False)
            options = [Option(Content(e.label()), id=str(i), disabled=bool(e.error))
                       for i, e in enumerate(self.entries)]
            yield OptionList(*options, id="settings-profiles")
            yield NumberRow("Grid step Δ (deg)", grid_step_rule(), f"{self.grid_step_deg:g}",
                            id="grid-step")
            yield Static(id="settings-reason", markup=False)
            with Horizontal(id="settings-buttons"):
                yield Button("Apply (a)", id="apply", variant="warning")
                yield Button("Close (esc)", id="close", variant="primary")
        yield ConsoleFooter()

    def on_mount(self) -> None:
        options = self.query_one("#settings-profiles", OptionList)
        options.highlighted = self._current_index()
        options.focus()
        # wider than the step screens' labels (app.tcss), so "(deg)" shows
        self.query_one("#grid-step-row .param-label", Label).styles.width = 19
        self._compact()

    def on_resize(self, event: events.Resize) -> None:
        self._compact()

    def _compact(self) -> None:
        self.query_one("#grid-step", Input).compact = self.size.height < COMPACT_BELOW_ROWS

    def _current_index(self) -> int | None:
        if self.current is not None:
            for i, e in enumerate(self.entries):
                if not e.error and e.path.resolve() == self.current.resolve():
                    return i
        return next((i for i, e in enumerate(self.entries) if not e.error), None)

    # ------------------------------------------------------------------ keys
    def on_key(self, event: events.Key) -> None:
        """Typed characters stay in the grid-step field (never a step or app key)."""
        if event.is_printable and isinstance(self.focused, Input):
            bound = self.active_bindings.get(event.key)
            if bound is None or bound.node is self or bound.node is self.app:
                event.stop()
                event.prevent_default()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        event.stop()
        if event.button.id == "apply":
            self.action_apply()
        else:
            self.action_cancel()

    def on_option_list_option_selected(self, event: OptionList.OptionSelected) -> None:
        event.stop()
        self.query_one("#grid-step", Input).focus()

    def on_input_submitted(self, event: Input.Submitted) -> None:
        event.stop()
        self.action_apply()

    def on_input_changed(self, event: Input.Changed) -> None:
        """A changed grid step: the refusal shown was about the value before."""
        self.query_one("#settings-reason", Static).update("")
        self._check_grid()

    def on_option_list_option_highlighted(self, event: OptionList.OptionHighlighted) -> None:
        """Another profile chosen: the refusal shown was about the one before."""
        self.query_one("#settings-reason", Static).update("")
        self._check_grid()

    def _check_grid(self) -> None:
        """The typed grid step against the chosen profile's θ range, as typed: a whole number
        of steps and at most the node cap (the reason under the field; Apply refuses it)."""
        row = self.query_one("#grid-step-row", NumberRow)
        field, entry = row.field, self.chosen()
        reason = ""
        if not field.rule.reason(field.value) and entry is not None and entry.range_deg:
            problems = grid_step_problems(*entry.range_deg, field.rule.parse(field.value))
            reason = f"grid step Δ: {problems[0].reason}" if problems else ""
        field.extra_reason = reason
        row.revalidate()

    def action_cancel(self) -> None:
        self.dismiss(None)

    # ------------------------------------------------------------------ apply
    def refuse(self, reason: str) -> None:
        self.query_one("#settings-reason", Static).update(Content(f"Not applied: {reason}"))

    def chosen(self) -> ProfileEntry | None:
        i = self.query_one("#settings-profiles", OptionList).highlighted
        return None if i is None or not 0 <= i < len(self.entries) else self.entries[i]

    def action_apply(self) -> None:
        """Check the choice (grid step as typed, the whole profile at that step), then ask."""
        if self.console.moving:
            self.refuse("the wrist is moving (SPACE stops it); apply when it stands still")
            return
        if self.checking:
            return
        entry = self.chosen()
        if entry is None or entry.error:
            self.refuse("choose a readable profile in the list")
            return
        try:
            step = self.query_one("#grid-step-row", NumberRow).number()
        except BadInputError as exc:
            self.refuse(exc.message)
            return
        if (self.current is not None and entry.path.resolve() == self.current.resolve()
                and step == self.grid_step_deg):
            self.refuse("this profile and grid step are already in use")
            return
        self.checking = True
        self.query_one("#settings-reason", Static).update(Content("checking the profile …"))
        self._check(SwitchRequest(entry.path, step))

    @work(thread=True, exclusive=True, exit_on_error=False, group="settings")
    def _check(self, request: SwitchRequest) -> None:
        try:
            profile = with_grid_step(load_profile(request.profile_path), request.grid_step_deg,
                                     source=f"{request.profile_path} at grid step "
                                            f"{request.grid_step_deg:g}°")
        except SpmError as exc:
            self.app.call_from_thread(self._checked, request, exc.message)
            return
        except Exception as exc:  # an unexpected failure is refused, never a traceback
            self.app.call_from_thread(self._checked, request,
                                      f"internal error ({type(exc).__name__}): {exc}")
            return
        self.app.call_from_thread(self._checked, request, "", profile.name)

    def _checked(self, request: SwitchRequest, error: str, name: str = "") -> None:
        self.checking = False
        if self.app.screen is not self:  # closed (esc) while the profile was checked
            return
        if error:
            self.refuse(error)
            return
        self.query_one("#settings-reason", Static).update("")
        body = (f"Restart the console with profile {name} ({request.profile_path}) at grid "
                f"step {request.grid_step_deg:g}°? The servos are disconnected, the motion "
                "process and the 3D view closed; the new console starts at the connect step, "
                "and its workspace step loads (or builds) the workspace for this grid step.")
        self.app.push_screen(ConfirmScreen("Restart with the new settings?", body),
                             lambda yes: self._confirmed(request) if yes else None)

    def _confirmed(self, request: SwitchRequest) -> None:
        if self.console.moving:  # it may have started while the question was open
            self.refuse("the wrist is moving (SPACE stops it); apply when it stands still")
            return
        self.dismiss(request)
