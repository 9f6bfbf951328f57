"""Step 1: connect to the servo bus, show each servo's status, home the wrist."""

from __future__ import annotations

from typing import ClassVar

from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Vertical
from textual.content import Content
from textual.widgets import DataTable, Static

from spm_console.formatting import fmt_deg
from spm_console.tui.messages import Connected, MotionDone, Outcome, PositionRead, Telemetry
from spm_console.tui.screens.base import StepScreen
from spm_console.tui.widgets.confirm import ConfirmScreen


class ConnectScreen(StepScreen):
    MODE = "connect"
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("c", "connect", "Connect"),
        Binding("h", "home", "Home"),
        Binding("r", "read", "Read"),
    ]

    def compose_body(self) -> ComposeResult:
        with Vertical(classes="body"):
            yield Static(id="bus-info", markup=False)
            yield DataTable(id="servos", cursor_type="none", zebra_stripes=True)
            yield Static(id="pose-info", markup=False)

    def on_mount(self) -> None:
        table = self.query_one("#servos", DataTable)
        table.add_columns("joint", "id", "model", "firmware", "temperature", "voltage",
                          "hardware error")
        self.show_bus()
        if self.session.bus is None:
            self.action_connect()

    # ------------------------------------------------------------------ actions
    def action_connect(self) -> None:
        if self.console.moving:
            return
        self.run_blocking("connect", lambda: Connected(self.session.connect()),
                          f"connecting to the {self.session.bus_label} …")

    def action_read(self) -> None:
        if self.session.bus is None:
            self.status.error("not connected: press c to connect")
            return
        self.run_blocking("read", lambda: PositionRead(self.session.read_position()),
                          "reading the motor angles …")

    def action_home(self) -> None:
        s = self.session
        if s.bus is None:
            self.status.error("not connected: press c to connect first")
            return
        if self.busy_op or self.console.moving:
            self.status.error("busy: wait for the current operation")
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
        on_sample = self.console.telemetry_sink(self)
        self.console.moving = True
        if not self.run_blocking("home", lambda: MotionDone("home", self.session.home(on_sample)),
                                 "homing …"):
            self.console.moving = False

    # ------------------------------------------------------------------ results
    def handle_done(self, outcome: Outcome) -> None:
        if isinstance(outcome, Connected):
            n = len(outcome.state.statuses)
            self.status.ok(f"connected: {n} servos answer on the {self.session.bus_label}")
        elif isinstance(outcome, PositionRead):
            self.status.ok(f"θ = {fmt_deg(outcome.theta_deg)}")
        elif isinstance(outcome, MotionDone):
            result = outcome.result
            self.console.moving = False
            self.console.after_motion(result)
            if result.ok:
                self.status.ok(f"homed: {result.message}. Log: {result.log_dir}")
            else:
                self.status.error(f"homing stopped: {result.message}. Log: {result.log_dir}")
        self.show_bus()

    def handle_failed(self, op: str, message: str) -> None:
        if op == "home":
            self.console.moving = False
        self.show_bus()

    def on_telemetry(self, message: Telemetry) -> None:
        message.stop()
        s = message.sample
        self.query_one("#pose-info", Static).update(Content(
            f"homing … t = {s.t:5.2f} s   θ = {fmt_deg(s.measured_deg)}   "
            f"tracking error {s.tracking_error_deg:.2f}°"))

    # ------------------------------------------------------------------ view
    def show_bus(self) -> None:
        s = self.session
        p = s.profile.bus
        if s.bus_state is None:
            info = (f"Bus: {s.bus_label} (protocol {p.protocol}, {p.baud} baud) — not connected")
        else:
            info = (f"Bus: {s.bus_label} (protocol {p.protocol}, {p.baud} baud), "
                    f"profile {s.profile.name}: {len(s.bus_state.statuses)} servos answer")
            if not s.bus_state.emulator_realtime_granted:  # said only when something is wrong
                info += (f"\nEmulated servos NOT real-time ({s.bus_state.emulator_realtime}): "
                         "replies may be late under load")
        self.query_one("#bus-info", Static).update(Content(info))
        table = self.query_one("#servos", DataTable)
        table.clear()
        if s.bus_state is not None:
            for j, st in enumerate(s.bus_state.statuses, start=1):
                table.add_row(
                    str(j), str(st.id), str(st.model_number),
                    "-" if st.firmware is None else str(st.firmware),
                    "-" if st.temperature_c is None else f"{st.temperature_c:.0f} °C",
                    "-" if st.voltage_v is None else f"{st.voltage_v:.1f} V",
                    "none" if st.hardware_error == 0 else f"0x{st.hardware_error:02x}",
                )
        if s.theta_deg is None:
            pose = "θ: unknown (not connected)"
        else:
            pose = f"θ = {fmt_deg(s.theta_deg)}   homed: {'yes' if s.homed else 'no'}"
        self.query_one("#pose-info", Static).update(Content(pose))
        if s.theta_deg is not None:
            self.console.view.show_theta(s.theta_deg)
