"""Step 1: connect to the servo bus, watch each servo's health live, home the wrist, and the
servo tools: torque on/off per joint, jog one joint, reboot a servo.

The health table refreshes every :data:`HEALTH_EVERY_S` while the wrist is idle (a timer
starts one status read in a worker, never a second while one is out; not while a motion
runs: the servo loop owns the bus then). Angles in degrees.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import ClassVar, Literal

from textual import work
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Vertical
from textual.content import Content
from textual.message import Message
from textual.widgets import Input, Static

from spm_console.config.models import servo_limits_deg
from spm_console.errors import SpmError
from spm_console.formatting import fmt_deg
from spm_console.motion.segments import ExecutionResult
from spm_console.motion.servo_tools import ServoHealth, jog_target
from spm_console.refusals import Refusal, worded
from spm_console.services.session import SampleCallback
from spm_console.tui.messages import (
    Connected,
    IdentifyDone,
    MotionDone,
    Outcome,
    PositionRead,
    ServoToolDone,
    Telemetry,
)
from spm_console.tui.screens.base import describe_error
from spm_console.tui.screens.connect_identify import IdentifyStep
from spm_console.tui.widgets.confirm import ConfirmScreen
from spm_console.tui.widgets.servo_health import JogStepField, ServoTable

#: Period of the live status read while idle, s (2.5 reads a second).
HEALTH_EVERY_S = 0.4
TOOLS_HELP = ("↑↓ choose a joint · t torque on/off · - / + jog it by the step (homed only) · "
              "b reboot it (clears a hardware error) · i identify the servos (homed only)")


class HealthPolled(Message):
    """A live status read finished (``health``), or failed (``error``)."""

    def __init__(self, health: ServoHealth | None, error: str = "") -> None:
        super().__init__()
        self.health = health
        self.error = error


class ConnectScreen(IdentifyStep):
    MODE = "connect"
    AUTO_FOCUS = "#servos"  # arrows choose the joint; letters still reach the screen
    DEFAULT_CSS = """
    ConnectScreen #health-info, ConnectScreen #tools-help { height: auto; color: $text-muted; }
    ConnectScreen #identify-result { height: auto; margin: 1 0 0 0; display: none; }
    """
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("c", "connect", "Connect"),
        Binding("h", "home", "Home"),
        Binding("r", "read", "Read"),
        Binding("t", "torque", "Torque"),
        Binding("minus", "jog(-1)", "Jog−", key_display="-"),
        Binding("plus,equals_sign", "jog(1)", "Jog+", key_display="+"),
        Binding("b", "reboot", "Reboot"),
        Binding("i", "identify", "Identify", tooltip="the identification experiment: fit the "
                "servo model as it is and write a profile with it (homed only)"),
    ]

    def __init__(self) -> None:
        super().__init__()
        self._polling = False
        self._health_error = ""

    def compose_body(self) -> ComposeResult:
        with Vertical(classes="body"):
            yield Static(id="bus-info", markup=False)
            yield ServoTable(self.session.profile.bus.protocol, id="servos")
            yield Static(id="health-info", markup=False)
            yield Static(id="pose-info", markup=False)
            yield JogStepField(id="jog-row")
            yield Static(TOOLS_HELP, id="tools-help", markup=False)
            yield Static(id="identify-result", markup=False)

    @property
    def table(self) -> ServoTable:
        return self.query_one("#servos", ServoTable)

    def on_mount(self) -> None:
        self.show_bus()
        self.set_interval(HEALTH_EVERY_S, self._poll)
        if self.session.bus is None:
            self.action_connect()

    # ------------------------------------------------------------------ live status
    def _poll(self) -> None:
        """Timer: one status read at a time, only while idle and shown."""
        s = self.session
        if self._polling or s.bus is None or self.busy_op or not self.is_active:
            return
        if self.console.moving or s.moving.is_set():
            self._show_health_line()
            return
        self._polling = True
        self._poll_worker()

    @work(thread=True, group="servo-health", exit_on_error=False)
    def _poll_worker(self) -> None:
        try:
            health = self.session.tools.servo_status()
        except BaseException as exc:  # a message, never a traceback
            self.post_message(HealthPolled(None, describe_error(exc)))
            return
        self.post_message(HealthPolled(health))

    def on_health_polled(self, message: HealthPolled) -> None:
        message.stop()
        self._polling = False
        if message.error and (self.console.moving or self.session.moving.is_set()):
            return  # a motion began meanwhile: the line says "moving", not an error
        self._health_error = message.error
        self.show_bus()

    # ------------------------------------------------------------------ actions
    def action_connect(self) -> None:
        if self.console.moving:
            return
        s = self.session
        if s.bus is None:
            self._connect()
            return
        restart = ("the emulated servos too: they start again at their first pose, torque off"
                   if s.sim else "the servos keep their goal and torque")
        body = (f"The {s.bus_label} is connected{' and the wrist homed' if s.homed else ''}. "
                f"Connecting again restarts the motion process ({restart}); the wrist must be "
                "homed again before it moves.")
        self.app.push_screen(ConfirmScreen("Connect again?", body), self._reconnect_confirmed)

    def _reconnect_confirmed(self, yes: bool | None) -> None:
        if yes:
            self._connect()
        else:
            self.status.ok("still connected: nothing restarted")

    def _connect(self) -> None:
        s = self.session

        def connect() -> Connected:
            self._health_error = ""
            restarted = s.sim and s.bus is not None
            state = s.connect()
            try:  # the table full at once (the timer keeps it fresh)
                s.tools.servo_status()
            except SpmError as exc:
                self._health_error = exc.message
            return Connected(state, restarted)

        self.run_blocking("connect", connect, f"connecting to the {s.bus_label} …")

    def action_read(self) -> None:
        if self.session.bus is None:
            self.status.error("not connected: press c to connect")
            return
        self.run_blocking("read", lambda: PositionRead(self.session.read_position()),
                          "reading the motor angles …")

    def action_home(self) -> None:
        s = self.session
        if not self._ready("home"):
            return
        here = fmt_deg(s.theta_deg) if s.theta_deg is not None else "unknown"
        home = fmt_deg(s.profile.home.theta_deg)
        body = (f"The wrist moves from θ = {here} to home θ = {home} in a straight line at "
                f"≤ {s.profile.safety.home_speed_degps:g}°/s on the {s.bus_label}.\n"
                "Press SPACE at any time to stop it.")
        self.app.push_screen(ConfirmScreen("Home the wrist?", body), self._home_confirmed)

    def _home_confirmed(self, yes: bool | None) -> None:
        if not yes:
            self.status.ok("homing cancelled: nothing moved")
            return
        self._start_motion("home", "homing", lambda on_sample: self.session.home(on_sample))

    def _start_motion(self, kind: Literal["home", "jog"], label: str,
                      fn: Callable[[SampleCallback], ExecutionResult]) -> None:
        """A motion through the runtime (E-stop banner up, steps locked until it ends)."""
        on_sample = self.console.telemetry_sink(self)
        self.console.moving = True
        self._motion_label = label
        if not self.run_blocking(kind, lambda: MotionDone(kind, fn(on_sample)), f"{label} …"):
            self.console.moving = False

    def action_torque(self) -> None:
        if not self._ready("torque"):
            return
        s, j = self.session, self.table.joint
        on = s.tools.health is None or not s.tools.health.joints[j - 1].torque_on
        if on:
            self._run_tool("torque on", j)
            return
        body = (f"Joint {j} goes limp: the wrist can sag under its own weight or be moved by "
                "hand. " + ("The wrist will no longer count as homed (home it again before "
                            "executing)." if s.homed else "The other joints keep their torque."))
        self.app.push_screen(ConfirmScreen(f"Torque off joint {j}?", body),
                             lambda yes: self._tool_confirmed(yes, "torque off", j))

    def action_reboot(self) -> None:
        if not self._ready("reboot"):
            return
        s, j = self.session, self.table.joint
        if s.profile.bus.protocol != "2.0":
            self.status.error("reboot: Protocol 1.0 has no REBOOT instruction; power-cycle "
                              "the servos to clear a hardware error")
            return
        ident = s.profile.bus.joints[j - 1].id
        hw = "unknown" if s.tools.health is None else s.tools.health.joints[j - 1].hardware_text
        body = (f"Servo id {ident} (joint {j}) restarts; a latched hardware error (now: {hw}) "
                "clears if its cause is gone. It comes back with torque OFF: the joint goes "
                "limp" + (" and the wrist will no longer count as homed." if s.homed else ".")
                + " The other servos keep theirs.")
        self.app.push_screen(ConfirmScreen(f"Reboot joint {j}?", body),
                             lambda yes: self._tool_confirmed(yes, "reboot", j))

    def _tool_confirmed(self, yes: bool | None, action: str, joint: int) -> None:
        if not yes:
            self.status.ok(f"{action} cancelled: nothing changed")
            return
        self._run_tool(action, joint)

    def _run_tool(self, action: str, joint: int) -> None:
        s = self.session
        if action == "reboot":
            self.run_blocking("reboot", lambda: ServoToolDone("reboot", joint, s.tools.reboot_servo(joint)),
                              f"rebooting joint {joint} …")
        elif action == "torque on":
            self.run_blocking("torque", lambda: ServoToolDone(
                "torque on", joint, s.tools.set_torque(joint, True)), f"torque on, joint {joint} …")
        else:
            self.run_blocking("torque", lambda: ServoToolDone(
                "torque off", joint, s.tools.set_torque(joint, False)), f"torque off, joint {joint} …")

    def on_input_submitted(self, event: Input.Submitted) -> None:
        if event.input.id == "jog-step":
            event.stop()
            self.table.focus()  # back to choosing joints

    def action_jog(self, direction: int) -> None:
        s = self.session
        if not self._ready("jog"):
            return
        step = self.query_one(JogStepField).check()
        if step is None:
            self.status.error("jog refused: the jog step is invalid (see beside it)")
            return
        if not s.homed:
            self.status.error(f"jog refused: {worded(Refusal.NOT_HOMED, 'console')}")
            return
        j, delta = self.table.joint, direction * step
        if s.theta_deg is None:
            self.status.error("jog refused: the present position is unknown; press r to read it")
            return
        try:
            target = jog_target(s.theta_deg, j, delta, servo_limits_deg(s.profile))
        except SpmError as exc:
            self.status.error(exc.message)
            return
        body = (f"Joint {j} moves by {delta:+g}°, from {s.theta_deg[j - 1]:.2f}° to "
                f"{target[j - 1]:.2f}° (servo limits checked), in a straight line at "
                f"≤ {s.profile.safety.home_speed_degps:g}°/s; the other joints hold. The runtime "
                "verifies the move before torque-on and logs it like any run.\n"
                "Press SPACE at any time to stop it.")
        self.app.push_screen(ConfirmScreen(f"Jog joint {j} by {delta:+g}°?", body),
                             lambda yes: self._jog_confirmed(yes, j, delta))

    def _jog_confirmed(self, yes: bool | None, joint: int, delta: float) -> None:
        if not yes:
            self.status.ok("jog cancelled: nothing moved")
            return
        self._start_motion("jog", f"jogging joint {joint} by {delta:+g}°",
                           lambda on_sample: self.session.tools.jog(joint, delta, on_sample))

    # ------------------------------------------------------------------ results
    def handle_done(self, outcome: Outcome) -> None:
        if isinstance(outcome, Connected):
            n = len(outcome.state.statuses)
            restart = ""
            if outcome.restarted_emulator:
                restart = (": the emulated servos started again at θ = "
                           f"{fmt_deg(self.session.theta_deg)}, torque off, not homed "
                           "(press h to home)")
            self.status.ok(f"connected: {n} servos answer on the {self.session.bus_label}{restart}")
        elif isinstance(outcome, PositionRead):
            self.status.ok(f"θ = {fmt_deg(outcome.theta_deg)}")
        elif isinstance(outcome, ServoToolDone):
            self._tool_done(outcome)
        elif isinstance(outcome, IdentifyDone):
            self.identify_done(outcome)
        elif isinstance(outcome, MotionDone):
            result = outcome.result
            self._health_error = ""
            self.console.moving = False
            self.console.after_motion(result)
            what = "homed" if outcome.kind == "home" else f"{self._motion_label}: done"
            if result.ok:
                self.status.run_result(f"{what}: {result.message}. Log: {result.log_dir}", result)
            else:
                self.status.run_result(f"{self._motion_label} stopped: {result.message}. "
                                       f"Log: {result.log_dir}", result)
        self.show_bus()

    def _tool_done(self, done: ServoToolDone) -> None:
        self._health_error = ""
        j = done.health.joints[done.joint - 1]
        unhomed = "; the wrist is no longer homed: press h to home it before any motion"
        if done.action == "reboot":
            text = f"joint {done.joint} rebooted: hardware error {j.hardware_text}, torque off"
            if j.hardware_error:
                self.status.error(text + " (the cause is still there)" + unhomed)
            else:
                self.status.ok(text + unhomed)
        elif done.action == "torque off":
            self.status.ok(f"torque off, joint {done.joint}" + unhomed)
        else:
            at = "" if j.position_deg is None else f" at {j.position_deg:.2f}°"
            self.status.ok(f"torque on, joint {done.joint}: it holds where it is{at}")

    def handle_failed(self, op: str, message: str) -> None:
        if op in ("home", "jog", "identify"):
            self.console.moving = False
        self.show_bus()

    def on_telemetry(self, message: Telemetry) -> None:
        message.stop()
        s = message.sample
        self.query_one("#pose-info", Static).update(Content(
            f"{self._motion_label} … t = {s.t:5.2f} s   θ = {fmt_deg(s.measured_deg)}   "
            f"tracking error {s.tracking_error_deg:.2f}°"))

    def refresh_view(self) -> None:
        super().refresh_view()
        self._show_health_line()

    # ------------------------------------------------------------------ view
    def _show_health_line(self) -> None:
        s = self.session
        if s.bus is None:
            text = ""
        elif self.console.moving or s.moving.is_set():
            text = "moving: live status paused until the wrist stops (the servo loop owns the bus)"
        elif self._health_error:
            text = f"live status: {self._health_error}"
        else:
            text = f"live status, read every {HEALTH_EVERY_S:g} s while the wrist is idle"
            h = s.tools.health
            if h is not None and h.silent:
                text += " · no reply from joint " + ", ".join(map(str, h.silent))
            if h is not None and h.faulted:
                text += (" · hardware error on joint " + ", ".join(map(str, h.faulted))
                         + ": choose it and press b to reboot it")
        self.query_one("#health-info", Static).update(Content(text))

    def show_bus(self) -> None:
        s = self.session
        p = s.profile.bus
        if s.bus_state is None:
            info = (f"Bus: {s.bus_label} (protocol {p.protocol}, {p.baud} baud) — not connected")
        else:
            fw = sorted({st.firmware for st in s.bus_state.statuses if st.firmware is not None})
            info = (f"Bus: {s.bus_label} (protocol {p.protocol}, {p.baud} baud), "
                    f"profile {s.profile.name}: {len(s.bus_state.statuses)} servos answer"
                    + (f", firmware {', '.join(map(str, fw))}" if fw else ""))
            if not s.bus_state.emulator_realtime_granted:  # said only when something is wrong
                info += (f"\nEmulated servos NOT real-time ({s.bus_state.emulator_realtime}): "
                         "replies may be late under load")
        self.query_one("#bus-info", Static).update(Content(info))
        self.table.show(s.bus_state, s.tools.health, bool(self._health_error))
        self._show_health_line()
        if s.theta_deg is None:
            pose = "θ: unknown (not connected)"
        else:
            pose = f"θ = {fmt_deg(s.theta_deg)}   homed: {'yes' if s.homed else 'no'}"
        self.query_one("#pose-info", Static).update(Content(pose))
        self.console.view.show_theta(s.theta_deg)  # None (not connected): no solid wrist
