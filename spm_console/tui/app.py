"""The operator console app and its one startup factory, :func:`make_app`.

The CLI (``spm-console tui``), the tests and the benchmark all build the app here,
so they exercise what operators run.
"""

from __future__ import annotations

import asyncio
import signal
import threading
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any, ClassVar

from textual import work
from textual.actions import SkipAction
from textual.app import App, SystemCommand
from textual.binding import Binding, BindingType
from textual.command import CommandPalette
from textual.dom import DOMNode
from textual.reactive import reactive
from textual.screen import Screen

from spm_console.config.schema import Profile
from spm_console.errors import ExitCode
from spm_console.services.session import Session
from spm_console.store.form_memory import FormMemory
from spm_console.system.signals import install_stop_handler
from spm_console.tui.messages import Telemetry
from spm_console.tui.screens.base import COMPACT_BELOW_COLUMNS, COMPACT_BELOW_ROWS, StepScreen
from spm_console.tui.screens.commission import CommissionScreen
from spm_console.tui.screens.connect import ConnectScreen
from spm_console.tui.screens.execute import ExecuteScreen
from spm_console.tui.screens.fk import FkScreen
from spm_console.tui.screens.help import HelpScreen, KeyEntry, key_entries, step_actions
from spm_console.tui.screens.logs import LogsScreen
from spm_console.tui.screens.plan import PlanScreen
from spm_console.tui.screens.settings import SettingsScreen
from spm_console.tui.screens.workspace import WorkspaceScreen
from spm_console.tui.switch import KeptWorkspace, SwitchRequest
from spm_console.tui.widgets.confirm import QuitConfirm
from spm_console.tui.widgets.estop import ESTOP_KEY
from spm_console.tui.widgets.steps import STEPS
from spm_console.viewer.view import MeshcatView, NullView, WristView

#: The settings' name in the key list and the palette (which searches titles only: "grid" or
#: "profile" must find it).
SETTINGS_TITLE = "Settings: profile, workspace grid step"
#: How long the note after a restart with other settings stays up, s (the console connects
#: meanwhile).
NOTE_TIMEOUT_S = 30
#: Shortest interval between two telemetry updates of the UI, s.
TELEMETRY_EVERY_S = 0.1


def _step_bindings() -> list[Binding]:
    """F10 and F1…F6, ctrl+0…6 (where the terminal sends them) switch steps from anywhere,
    even inside a field; the digits only while no field or dropdown has focus (the step
    screens keep typed characters away from bindings). The step bar shows the keys."""
    out = []
    for s in STEPS:
        action, desc = f"step('{s.mode}')", f"Step {s.key}: {s.title}"
        out += [
            Binding(s.fkey, action, desc, show=False, priority=True, key_display=s.fkey_display),
            Binding(s.key, action, desc, show=False),
            Binding(f"ctrl+{s.key}", action, desc, show=False, priority=True),
        ]
    return out


class SpmConsoleApp(App[int | SwitchRequest]):
    """Seven step screens (Textual modes, step 0 commissioning) over one :class:`Session`. It exits with a process
    exit code, or with a :class:`SwitchRequest` when the operator applied other settings
    (``spm-console tui`` then starts a new console for them)."""

    TITLE = "spm-console"
    CSS_PATH = "app.tcss"
    ENABLE_COMMAND_PALETTE = True
    COMMAND_PALETTE_DISPLAY = "^p"
    #: Screens get the class "-narrow" below 100 columns and "-short" below 36 rows (app.tcss
    #: stacks the side-by-side panels and fixes plot heights there; fields turn compact).
    HORIZONTAL_BREAKPOINTS = [(0, "-narrow"), (COMPACT_BELOW_COLUMNS, "-wide")]  # noqa: RUF012
    VERTICAL_BREAKPOINTS = [(0, "-short"), (COMPACT_BELOW_ROWS, "-tall")]  # noqa: RUF012
    MODES: ClassVar[dict[str, str | Callable[[], Screen[Any]]]] = {
        "commission": CommissionScreen,
        "connect": ConnectScreen,
        "fk": FkScreen,
        "workspace": WorkspaceScreen,
        "plan": PlanScreen,
        "execute": ExecuteScreen,
        "logs": LogsScreen,
    }
    BINDINGS: ClassVar[list[BindingType]] = [
        *_step_bindings(),
        Binding("question_mark", "help", "Keys", key_display="?",
                tooltip="this list (also in the palette, ctrl+p)"),
        Binding("q", "quit", "Quit", tooltip="asks first (q again or y); refused while the wrist "
                "moves"),
        # the palette finds a command by its title only: the title names what it sets
        Binding("ctrl+o", "settings", SETTINGS_TITLE, show=False, priority=True,
                tooltip="choose another profile or workspace grid step (applying restarts "
                "the console)"),
        Binding("f7", "settings", SETTINGS_TITLE, show=False, priority=True, key_display="F7"),
        Binding(ESTOP_KEY, "estop", "E-STOP", priority=True, key_display="SPACE",
                tooltip="stops any motion (active while the wrist moves)"),
    ]

    moving: reactive[bool] = reactive(False)
    """True while the wrist moves (homing or execution): E-stop shown, steps locked."""

    def __init__(self, session: Session, view: WristView, start_viewer: bool = True,
                 profile_path: Path | None = None, note: str = "") -> None:
        super().__init__()
        self.session = session
        self.view = view
        self.profile_path = profile_path
        """The profile file in use (None: not from a file); the settings list it."""
        self._note = note
        """Said once the console is up (e.g. after a restart with other settings)."""
        self.sub_title = (f"{session.profile.name}, grid step "
                          f"{session.profile.workspace.step_deg:g}°")
        self.build_cancel: threading.Event | None = None
        """Set by the workspace step while it loads or builds; setting the event cancels
        the build at its next progress report."""
        self._start_viewer = start_viewer and isinstance(view, MeshcatView)
        self.viewer_url: str | None = None
        self.fk_done = False

        self.form_memory = FormMemory()
        """Typed form values per profile, kept between sessions ($SPM_CONSOLE_CONFIG)."""
        self.live_samples: list[Any] = []
        self.stop_elsewhere: Callable[[str, bool], bool] | None = None
        """The E-stop of motions the session does not run (commissioning's own motion
        processes); None when none runs."""
        self._closed = False
        self._restore_signals: Callable[[], None] = lambda: None
        self._exit_code_on_signal: int | None = None
        self._loop: asyncio.AbstractEventLoop | None = None

    # ------------------------------------------------------------------ lifecycle
    async def on_mount(self) -> None:
        await self.switch_mode("connect")  # before the note: a toast needs its screen up
        self._loop = asyncio.get_running_loop()
        self._restore_signals = install_stop_handler(self._on_stop_signal)
        if self._start_viewer:
            self._launch_viewer()
        if self._note:
            self.notify(self._note, title="Settings", timeout=NOTE_TIMEOUT_S, markup=False)

    def _on_stop_signal(self, sig: signal.Signals) -> None:
        """SIGINT / SIGTERM / SIGHUP / SIGQUIT (signal handler, main thread): E-stop any motion
        at once, then leave through the app's own message loop (exiting straight from the
        signal handler leaves Textual hanging in its shutdown). Exit 20 when a motion was
        stopped, 130 otherwise (docs/cli-reference.md, "Exit codes")."""
        moving = self.session.estop(f"signal {sig.name}", by_signal=True)
        moving = self._estop_elsewhere(f"signal {sig.name}", True) or moving
        code = int(ExitCode.STOP_ESTOP if moving else ExitCode.INTERRUPTED)
        if self._exit_code_on_signal is None and self._loop is not None:
            self._exit_code_on_signal = code
            # the handler may have interrupted the event loop itself: only this call is safe
            self._loop.call_soon_threadsafe(self.call_later, self._terminate, code)

    def _terminate(self, code: int) -> None:
        self.shutdown()
        self.exit(code, return_code=code)

    @work(thread=True, exit_on_error=False, group="viewer")
    def _launch_viewer(self) -> None:
        assert isinstance(self.view, MeshcatView)
        try:
            url = self.view.start()
        except Exception as exc:  # the console works without the view
            msg = getattr(exc, "message", str(exc))
            self.call_from_thread(self.notify, f"3D view unavailable: {msg}", severity="warning",
                                  markup=False)
            return
        self.call_from_thread(self._viewer_ready, url)

    def _viewer_ready(self, url: str) -> None:
        self.viewer_url = url
        self.view.show_theta(self.session.theta_deg)  # None: no solid wrist
        self.refresh_screen()

    def shutdown(self) -> None:
        """Stop motion and any workspace build, close the bus and the viewer (idempotent;
        also on SIGTERM)."""
        if self._closed:
            return
        self._closed = True
        self.cancel_build()  # the app's exit waits for its worker threads
        self._estop_elsewhere("console closing", False)
        self.session.close()
        self.view.close()

    def on_unmount(self) -> None:
        self._restore_signals()
        self.shutdown()

    # ------------------------------------------------------------------ actions
    async def action_step(self, mode: str) -> None:
        await self._go_to(mode)

    async def _go_to(self, mode: str) -> bool:
        """Show step ``mode``; False (and a notice) while the wrist moves or a dialog waits."""
        if self.moving:
            self.notify("The wrist is moving: wait, or press SPACE to stop it.",
                        severity="warning")
            return False
        # The help and the palette close first; a dialog must be answered (it would stay
        # behind on the step it belongs to).
        while isinstance(self.screen, (HelpScreen, CommandPalette)):
            await self.screen.dismiss()
        if not isinstance(self.screen, StepScreen):
            self.notify("Answer the dialog first (y / n, esc cancels).", severity="warning")
            return False
        if self.current_mode != mode:
            await self.switch_mode(mode)
        return True

    def _wrist_moving(self) -> bool:
        return self.moving or self.session.moving.is_set()

    async def action_quit(self) -> None:
        """q and ctrl+q: ask first (q again or y quits); stop nothing by surprise (refused
        while the wrist moves: SPACE stops it first)."""
        if self._wrist_moving():
            self.notify("The wrist is moving: press SPACE to stop it before quitting.",
                        severity="warning")
            return
        if isinstance(self.screen, QuitConfirm):  # ctrl+q twice
            self.screen.dismiss(True)
            return
        self.push_screen(QuitConfirm(), self._quit_answered)

    def _quit_answered(self, yes: bool | None) -> None:
        if not yes:
            return
        if self._wrist_moving():  # started meanwhile: never quit under way
            self.notify("The wrist is moving: press SPACE to stop it before quitting.",
                        severity="warning")
            return
        self.shutdown()
        self.exit(0)

    async def action_settings(self) -> None:
        """The settings dialog (profile, grid step); applying restarts the console."""
        if self.moving:
            self.notify("The wrist is moving: settings wait until it stands still (SPACE "
                        "stops it).", severity="warning")
            return
        while isinstance(self.screen, (HelpScreen, CommandPalette)):
            await self.screen.dismiss()
        if isinstance(self.screen, SettingsScreen):
            return
        if not isinstance(self.screen, StepScreen):
            self.notify("Answer the dialog first (y / n, esc cancels).", severity="warning")
            return
        prof = self.session.profile
        self.push_screen(SettingsScreen(self.profile_path, prof.name,
                                        float(prof.workspace.step_deg)), self._apply_settings)

    def _apply_settings(self, request: SwitchRequest | None) -> None:
        self.restart_with(request)

    def restart_with(self, request: SwitchRequest | None) -> bool:
        """Exit with ``request`` (the CLI restarts the console with it: the settings applied,
        or the identified servo model), never while the wrist moves (False then)."""
        if request is None:
            return False
        if self._wrist_moving():
            self.notify("The wrist is moving: the console does not restart (SPACE stops it).",
                        severity="warning")
            return False
        self.shutdown()
        self.exit(request)
        return True

    def cancel_build(self) -> bool:
        """Cancel the running workspace load/build (False when none runs)."""
        cancel = self.build_cancel
        if cancel is None:
            return False
        cancel.set()
        return True

    def action_help(self) -> None:
        """Open the key list of the current screen (or close it)."""
        if isinstance(self.screen, HelpScreen):
            self.screen.dismiss(None)
            return
        self.push_screen(HelpScreen(self.screen))

    def _estop_elsewhere(self, reason: str, by_signal: bool) -> bool:
        stop = self.stop_elsewhere
        return stop is not None and stop(reason, by_signal)

    def action_estop(self) -> None:
        sent = self.session.estop("operator E-stop (SPACE)")
        if not (self._estop_elsewhere("operator E-stop (SPACE)", False) or sent):
            raise SkipAction()
        self.notify("E-STOP sent: the wrist holds still.", severity="error", timeout=6)

    # ------------------------------------------------------------------ command palette
    def get_system_commands(self, screen: Screen[Any]) -> Iterable[SystemCommand]:
        """Every action of ``screen`` and of the app (from the bindings, with their keys),
        the E-stop (also when nothing moves: it says so), every other step's own actions
        ("Plan: Solve" switches to the plan step, then solves), then Textual's theme,
        maximize and screenshot commands."""
        under = screen
        for node, entries in key_entries(under, self):
            where = "this screen" if node is under else "everywhere"
            for e in entries:
                estop = e.action == "estop"
                if e.single_action and (e.state is not False or estop):
                    note = ("nothing moves now; stops any motion while the wrist moves"
                            if estop and not self.moving else e.tooltip)
                    yield SystemCommand(e.description, f"key {e.keys_text} ({where})"
                                        + (f": {note}" if note else ""),
                                        self._palette_runner(e))
        here = getattr(under, "MODE", "")
        for step in STEPS:
            if step.mode == here:
                continue  # listed above, as this screen's
            for e in step_actions(self.MODES[step.mode], self):  # type: ignore[arg-type]
                yield SystemCommand(f"{step.title}: {e.description}",
                                    f"key {e.keys_text} on step {step.key} ({step.fkey_display}),"
                                    " which this command switches to first"
                                    + (f": {e.tooltip}" if e.tooltip else ""),
                                    self._palette_step_runner(step.mode, e))
        for cmd in super().get_system_commands(screen):
            if cmd.title not in ("Quit", "Keys"):  # ours are above (q refuses while moving)
                yield cmd

    def _palette_runner(self, entry: KeyEntry) -> Callable[[], Any]:
        node: DOMNode = entry.node

        async def run() -> None:
            if await self.run_action(entry.action, node):
                return
            if entry.action == "estop":
                self.notify("E-STOP: nothing moves now.", severity="information")
            else:
                self.notify(f"{entry.description}: not available now", severity="warning")

        return run

    def _palette_step_runner(self, mode: str, entry: KeyEntry) -> Callable[[], Any]:
        async def run() -> None:
            if not await self._go_to(mode):
                return
            if not await self.run_action(entry.action, self.screen):
                self.notify(f"{entry.description}: not available now", severity="warning")

        return run

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action == "estop":
            return self.moving
        return True  # a step key while the wrist moves is refused with a notice (_go_to)

    def watch_moving(self, moving: bool) -> None:
        # Nothing here touches timing: the servo loop runs in the motion process.
        self.refresh_bindings()
        self.refresh_screen()

    # ------------------------------------------------------------------ helpers for screens
    def telemetry_sink(self, screen: Screen[Any]) -> Callable[[Any], None]:
        """Callback for the executor thread: keep every sample, move the 3D view (it
        throttles itself) and tell ``screen`` at most every ``TELEMETRY_EVERY_S`` (the
        servo loop must not wait for the UI; Telemetry messages also coalesce)."""
        samples = self.live_samples
        view = self.view
        last = [-1.0]

        def on_sample(sample: Any) -> None:
            samples.append(sample)
            if sample.read_ok:
                view.show_theta(sample.measured_deg)
            if sample.t - last[0] >= TELEMETRY_EVERY_S:
                last[0] = sample.t
                screen.post_message(Telemetry(sample))

        return on_sample

    def after_motion(self, result: Any) -> None:
        self.view.show_theta(self.session.theta_deg)  # the last reading (None: unknown)

    def refresh_screen(self) -> None:
        screen = self.screen
        refresh = getattr(screen, "refresh_view", None)
        if callable(refresh) and screen.is_mounted:
            refresh()


def make_app(
    profile: Profile,
    port: str | None = None,
    sim: bool = True,
    viewer: bool = True,
    *,
    logs_root: Path | None = None,
    cache_dir: Path | None = None,
    faults: Sequence[Any] = (),
    initial_deg: Sequence[float] | None = None,
    profile_path: Path | None = None,
    note: str = "",
    kept: KeptWorkspace | None = None,
) -> SpmConsoleApp:
    """The console for ``profile`` (read from ``profile_path``, listed by the settings) on a
    serial ``port`` or the emulated bus (``sim``), with or without the meshcat view; ``note``
    is said once it is up; ``kept``: the workspace the console before had loaded, used when
    it is this profile's. Nothing is opened until the app runs."""
    session = Session(profile, port=port, sim=sim and port is None, logs_root=logs_root,
                      cache_dir=cache_dir, faults=faults, initial_deg=initial_deg,
                      emulator_process=True)
    if kept is not None and kept.fits(profile):
        session.wrist.workspace, session.wrist.cache_info = kept.workspace, kept.info
    view: WristView = MeshcatView(profile) if viewer else NullView()
    return SpmConsoleApp(session, view, start_viewer=viewer, profile_path=profile_path,
                         note=note)
