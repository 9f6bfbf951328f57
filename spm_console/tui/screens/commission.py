"""Step 0: commission the wrist as built (``spm-console commission`` in the console).

The operator names the servo bus and the IMU's port, says whether the wrist rests on its home
jig and whether the IMU stage runs, and starts (``s``, after a yes/no that says what moves).
Without an IMU (its port left empty) the map asks the operator, in a dialog, which leg's arm
each nudge moved and which way (:mod:`spm_console.tui.widgets.answer`).
The stages run in a worker thread (:mod:`spm_console.services.commissioning.stages`), each stage's line
streamed into the log on this step; the result (legs, ids, directions, tick offsets, the IMU
stage's residuals and what it leaves undetermined) stays here, the commissioned profile is
written beside the profile in use (``NAME.commissioned-TIME.toml``, as the CLI writes it) and
the console asks "Use the commissioned profile now?": yes restarts it on that profile with the
workspace kept (the bus is not part of the workspace's cache key).

Commissioning opens a motion process of its own for each stage: when the console's session
holds the same port, it is disconnected first and connected again after. SPACE (and a
terminating signal) reaches the stage's motion process through a
:class:`~spm_console.services.client.EstopRelay`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal, Vertical
from textual.content import Content
from textual.message import Message
from textual.widgets import Checkbox, Input, Label, RichLog, Static

from spm_console.config.checks import port_problem
from spm_console.config.plant import MAX_PAYLOAD_KG
from spm_console.config.schema import DEFAULT_PROFILE, Profile
from spm_console.errors import BadInputError, SpmError
from spm_console.tui.messages import CommissionDone, Outcome
from spm_console.tui.screens.base import StepScreen
from spm_console.tui.switch import SwitchRequest
from spm_console.tui.widgets.answer import asker
from spm_console.tui.widgets.checkbox import TickBox
from spm_console.tui.widgets.confirm import LongConfirm
from spm_console.tui.widgets.field import TextField
from spm_console.tui.widgets.number import NumberRule

if TYPE_CHECKING:
    from spm_console.services.client import EstopRelay
    from spm_console.services.commissioning.stages import Ask

#: Lines the stage log keeps.
LOG_LINES = 500
START_TITLE = "Commission the wrist?"
USE_TITLE = "Use the commissioned profile now?"
HELP_LINE = ("s starts (after a yes/no) · SPACE stops it · tab moves between the fields, esc "
             "leaves a field")


#: The payload's mass field: weighed, kg (empty: not known).
PAYLOAD_RULE = NumberRule("payload mass", "a mass in kg (weighed)", " kg", lo=0.0,
                          hi=MAX_PAYLOAD_KG, lo_open=True)


@dataclass(frozen=True)
class CommissionForm:
    """What the operator asked for."""

    bus: str
    imu: str
    jig: bool
    imu_stage: bool
    payload_kg: str = ""
    """As typed (empty: not weighed)."""

    def payload(self) -> float | None:
        """The payload's mass, kg (None: not given); BadInputError for a bad one."""
        return PAYLOAD_RULE.parse(self.payload_kg) if self.payload_kg.strip() else None


class CommissionStage(Message):
    """A stage's line from the worker (every one is shown: they never coalesce)."""

    def __init__(self, line: str) -> None:
        super().__init__()
        self.line = line


class CommissionScreen(StepScreen):
    MODE = "commission"
    DEFAULT_CSS = """
    CommissionScreen #commission-help { height: auto; color: $text-muted; }
    CommissionScreen #commission-reason { height: auto; color: $error; }
    CommissionScreen #stages { height: 1fr; min-height: 6; border: round $panel; }
    CommissionScreen #commission-result { height: auto; margin: 1 0 0 0; display: none; }
    CommissionScreen .param-label { width: 16; }
    """
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("s", "start", "Start", tooltip="find the servos, map them to legs (the IMU, or your "
                "answers), zero them on the jig, refine with the IMU; writes a profile (asks "
                "first)"),
    ]

    def __init__(self) -> None:
        super().__init__()
        self._stop: EstopRelay | None = None
        self._reason = ""
        """The refusal shown under the form ("" when none is)."""

    def compose_body(self) -> ComposeResult:
        s = self.session
        bus = "" if s.sim else (s.port or "")
        with Vertical(classes="body"):
            yield Static("Find the servos of the wrist as built, map them to legs with the IMU "
                         "on the platform (without one: you say which arm each nudge moved), "
                         "zero them on the home jig (or with the IMU where the wrist rests) "
                         "and write a profile for it beside the profile in use.", markup=False)
            with Horizontal(classes="param"):
                yield Label("Servo bus", classes="param-label", markup=False)
                yield TextField(bus, placeholder="/dev/ttyUSB0 or unix:…", id="bus-port")
            with Horizontal(classes="param"):
                yield Label("IMU (BNO055)", classes="param-label", markup=False)
                yield TextField("", placeholder="/dev/ttyUSB1 (empty: none, you answer)",
                                id="imu-port")
            yield TickBox("the wrist rests on its home jig, torque off (zero the servos there)",
                          False, id="jig")
            yield TickBox("IMU stage: verified poses across the region P, fit and verify",
                          True, id="imu-stage")
            with Horizontal(classes="param"):
                yield Label("Payload (kg)", classes="param-label", markup=False)
                yield TextField("", placeholder="weighed; empty: not known", id="payload-kg")
            yield Static(id="commission-reason", markup=False)
            yield Static(HELP_LINE, id="commission-help", markup=False)
            yield RichLog(id="stages", markup=False, highlight=False, wrap=True,
                          max_lines=LOG_LINES)
            yield Static(id="commission-result", markup=False)

    @property
    def log_view(self) -> RichLog:
        return self.query_one("#stages", RichLog)

    def form(self) -> CommissionForm:
        return CommissionForm(self.query_one("#bus-port", TextField).value,
                              self.query_one("#imu-port", TextField).value,
                              self.query_one("#jig", TickBox).value,
                              self.query_one("#imu-stage", TickBox).value,
                              self.query_one("#payload-kg", TextField).value)

    def form_problem(self, f: CommissionForm) -> str:
        """Why ``f`` cannot start ("" when it can)."""
        from spm_console.services.commissioning.run import options_problem

        why = port_problem(f.bus, "servo bus") or (f.imu and port_problem(f.imu, "IMU port"))
        if why:
            return why
        if f.imu_stage and not f.imu:
            return ("the IMU stage needs the IMU: type its port, or untick the IMU stage (the "
                    "map then asks you which leg each nudge moved)")
        try:
            mass = f.payload()
        except BadInputError as exc:
            return exc.message
        return options_problem(f.bus, f.imu or None, f.jig, f.imu_stage, mass)

    def on_input_changed(self, message: Input.Changed) -> None:
        self._recheck_reason()

    def on_checkbox_changed(self, message: Checkbox.Changed) -> None:
        self._recheck_reason()

    def _recheck_reason(self) -> None:
        """A refusal shown under the form follows the form as it is edited (gone once the
        form can start): it is shown first by ``s``."""
        if self._reason:
            self._show_reason(self.form_problem(self.form()))

    def _show_reason(self, why: str) -> None:
        self._reason = why
        self.query_one("#commission-reason", Static).update(Content(why))

    # ------------------------------------------------------------------ start
    def action_start(self) -> None:
        if self.busy_op or self.console.moving or self.session.moving.is_set():
            self.status.error("commission: busy, wait for the current operation")
            return
        f = self.form()
        why = self.form_problem(f)
        self._show_reason(why)
        if why:
            self.status.refused(f"commission refused: {why}; nothing started")
            return
        self.app.push_screen(LongConfirm(START_TITLE, self._question(f)),
                             lambda yes: self._confirmed(yes, f))

    def _question(self, f: CommissionForm) -> str:
        from spm_console.services.commissioning.imu_stage import (
            FIT_POSES,
            HELD_OUT,
            POSE_SPEED_DEGPS,
        )
        from spm_console.services.commissioning.rest_zero import SWING_DEG
        from spm_console.services.commissioning.stages import MAP_NUDGE_DEG, MAP_SPEED_DEGPS

        lines = [f"Servo bus {f.bus}, " + (f"IMU on {f.imu}." if f.imu else
                                            "no IMU: you say what each nudge moved."),
                 "1. Discover: every id 0..252 pinged on both protocols (nothing moves)."]
        if f.jig:
            lines.append("2. Jig: torque off, each servo's ticks averaged at the home jig.")
        elif f.imu:
            lines.append(f"2. Zero at rest (no jig): after the map, each leg alone swings "
                         f"±{SWING_DEG:g}° about where it rests; the IMU's rotations give its "
                         "angle there.")
        lines.append(f"3. Map: each servo alone nudged {MAP_NUDGE_DEG:g}° at "
                     f"{MAP_SPEED_DEGPS:g}°/s and back, the others holding."
                     + ("" if f.imu else " While it is out you are asked which leg's arm "
                        "moved and which way (esc gives up; 'again' nudges it again)."))
        if f.imu_stage:
            lines.append(f"4. IMU stage: homing, then {FIT_POSES + HELD_OUT} verified poses "
                         f"across the workspace's region P at up to {POSE_SPEED_DEGPS:g}°/s; "
                         "fit and held-out verification.")
        if f.payload_kg.strip():
            lines.append(f"Payload {f.payload():g} kg (weighed): placed at the IMU stage's "
                         "first moment m·c / m, written as [plant] payload_kg.")
        if self._release_needed(f.bus):
            lines.append(f"The console's own connection to {f.bus} is closed first and opened "
                         "again after.")
        lines += ["The wrist moves: press SPACE at any time to stop it.",
                  "Then the commissioned profile is written beside the profile in use "
                  "(NAME.commissioned-TIME.toml); you are then asked whether to use it."]
        return "\n".join(lines)

    def _release_needed(self, bus: str) -> bool:
        s = self.session
        return s.bus is not None and not s.sim and s.port == bus

    def _confirmed(self, yes: bool | None, f: CommissionForm) -> None:
        if not yes:
            self.status.ok("commissioning cancelled: nothing moved")
            return
        from spm_console.services.client import EstopRelay

        stop = EstopRelay("commission")
        self._stop = stop
        self.console.stop_elsewhere = stop.estop
        self.set_focus(None)
        self.log_view.clear()
        self.query_one("#commission-result", Static).display = False
        self.console.moving = True
        if not self.run_blocking("commission", lambda: self._run(f, stop),
                                 "commissioning … (SPACE stops it)"):
            self._finished()

    def _run(self, f: CommissionForm, stop: EstopRelay) -> Outcome:
        """The worker: release the console's bus if it is the same port, commission, write
        the profile, connect again."""
        s = self.session
        release = self._release_needed(f.bus)
        if release:
            self._stage(f"console: closing its own connection to {f.bus}")
            s.disconnect()
        try:
            return commission_blocking(s.profile, self.console.profile_path, f, stop,
                                       self._stage, None if f.imu else self._asker(stop),
                                       s.logs_root)
        finally:
            if release:
                self._stage(f"console: connecting to {f.bus} again")
                try:
                    s.connect(check=False)
                except SpmError as exc:
                    self._stage(f"console: not connected again ({exc.message}); press 1, "
                                "then c")

    def _asker(self, stop: EstopRelay) -> Ask:
        """The operator, asked in a dialog from the worker (no IMU)."""
        from spm_console.services.commissioning.stages import ANSWER_TIMEOUT_S

        return asker(self.app, stop, "Commissioning: what moved?", ANSWER_TIMEOUT_S)

    def _stage(self, line: str) -> None:
        self.post_message(CommissionStage(line))

    def on_commission_stage(self, message: CommissionStage) -> None:
        message.stop()
        self.log_view.write(message.line)

    def _finished(self) -> None:
        self.console.moving = False
        self.console.stop_elsewhere = None
        self._stop = None

    # ------------------------------------------------------------------ result
    def handle_done(self, outcome: Outcome) -> None:
        if not isinstance(outcome, CommissionDone):
            return
        self._finished()
        self.log_view.write(f"written: {outcome.written}")
        self.status.ok(f"commissioned: legs {outcome.ids_text}; profile written: "
                       f"{outcome.written}")
        panel = self.query_one("#commission-result", Static)
        panel.update(Content("\n".join(outcome.lines)))
        panel.display = True
        self.app.push_screen(LongConfirm(USE_TITLE, self._use_question(outcome)),
                             lambda yes: self._use_answered(yes, outcome))

    def handle_failed(self, op: str, message: str) -> None:
        if op == "commission":
            self._finished()
            self.log_view.write(f"ended: {message}")

    def _use_question(self, done: CommissionDone) -> str:
        step = float(self.session.profile.workspace.step_deg)
        return "\n".join([
            f"Commissioned profile written: {done.written}",
            f"Yes: the console restarts on it at grid step {step:g}° (as the settings do): "
            "the servos are disconnected (home again), the workspace is kept (the bus is not "
            "part of it).",
            "No: the profile in use stays.", "", *done.lines])

    def _use_answered(self, yes: bool | None, done: CommissionDone) -> None:
        s = self.session
        if not yes:
            self.status.ok(f"the profile in use stays {s.profile.name}; the commissioned one "
                           f"is {done.written}")
            return
        why = (f"Commissioned profile in use: {done.written} (the console restarted on it; the "
               "workspace was kept). Home the wrist again (h).")
        request = SwitchRequest.keeping(done.written, s.profile, s.wrist.workspace, s.wrist.cache_info, why)
        if not self.console.restart_with(request):
            self.status.error("the console did not restart: the wrist is moving")


def commission_blocking(profile: Profile, profile_path: Path | None, f: CommissionForm,
                        stop: EstopRelay, on_stage: Callable[[str], None],
                        ask: Ask | None = None,
                        logs_root: Path | None = None) -> CommissionDone:
    """Commission (and refine with the IMU when asked), then write the profile beside
    ``profile_path`` (the default profile when the console has no file) as the CLI does;
    ``ask``: the operator, when there is no IMU; ``logs_root``: the console's run logs (the
    commissioning's and its IMU stage's runs are listed on the Logs step)."""
    from spm_console.services.commissioning.profile_out import commissioned_lines
    from spm_console.services.commissioning.run import CommissionRequest, run_commissioning

    req = CommissionRequest(f.bus, f.imu or None, f.jig, f.imu_stage, logs_root=logs_root,
                            payload_kg=f.payload())
    done = run_commissioning(profile, profile_path or DEFAULT_PROFILE, req, on_stage, stop,
                             ask)
    result, written = done.result, done.written
    ids = ", ".join(f"{m.leg}: id {m.id} ({'+' if m.direction > 0 else '−'})"
                    for m in result.legs)
    return CommissionDone(written, tuple(commissioned_lines(result, f.bus)), ids)
