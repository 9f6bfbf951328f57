"""Step 5: execute the plan — confirmation, live θ / velocity / tracking error per joint,
plots, elapsed and remaining time, the E-stop, then the outcome and the log path."""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal, Vertical
from textual.content import Content
from textual.widgets import DataTable, ProgressBar, Static

from spm_console.formatting import fmt_deg
from spm_console.tui.messages import MotionDone, Outcome, Telemetry
from spm_console.tui.screens.base import StepScreen
from spm_console.tui.widgets.confirm import ConfirmScreen
from spm_console.tui.widgets.plot import PlotView, joint_series

#: Live plot redraw interval, s (telemetry itself arrives every Ts, coalesced).
PLOT_EVERY_S = 0.5


class ExecuteScreen(StepScreen):
    MODE = "execute"
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("x", "execute", "Execute"),
        Binding("p", "next_plot", "Plot"),
    ]

    def __init__(self) -> None:
        super().__init__()
        self.plot_kind = 0
        self._last_plot = 0.0

    def compose_body(self) -> ComposeResult:
        with Vertical(classes="body"):
            yield Static(id="exec-plan", markup=False)
            with Horizontal(id="exec-live"):
                yield DataTable(id="joints", cursor_type="none")
                with Vertical(id="exec-time"):
                    yield Static(id="exec-clock", markup=False)
                    yield ProgressBar(total=100, id="exec-progress", show_eta=False)
            yield Static(id="exec-outcome", markup=False, classes="result")
            yield PlotView(id="exec-plot")

    def on_mount(self) -> None:
        t = self.query_one("#joints", DataTable)
        t.add_columns("joint", "ref. θ*", "measured θ", "dθ/dt (KF)", "error")
        for i in range(3):
            t.add_row(str(i + 1), "-", "-", "-", "-", key=str(i))
        self.refresh_view()

    def refresh_view(self) -> None:
        super().refresh_view()
        s = self.session
        if s.plan is None:
            text = "No plan yet: press 4 to plan a motion."
        else:
            p = s.plan
            text = (f"Plan: {p.kind.upper()} {fmt_deg(p.reference_deg[0])} → "
                    f"{fmt_deg(p.reference_deg[-1])}, {p.duration_s:.2f} s, on the {s.bus_label}"
                    + ("" if s.homed else "   (not homed: press 1, then h)"))
        self.query_one("#exec-plan", Static).update(Content(text))

    def action_execute(self) -> None:
        s = self.session
        if s.plan is None:
            self.status.error("no plan: press 4 and solve one first")
            return
        if s.bus is None or not s.homed:
            self.status.error("the wrist is not connected and homed: press 1, then c and h")
            return
        if self.busy_op or self.console.moving:
            self.status.error("busy: a motion is already running")
            return
        p = s.plan
        here = fmt_deg(s.theta_deg) if s.theta_deg is not None else "unknown"
        body = (f"The wrist moves on the {s.bus_label}: {p.kind.upper()} plan of "
                f"{p.duration_s:.2f} s from {fmt_deg(p.reference_deg[0])} to "
                f"{fmt_deg(p.reference_deg[-1])} (now at {here}; a straight approach move at "
                f"≤ {s.profile.safety.home_speed_degps:g}°/s comes first if needed).\n"
                "Press SPACE at any time to stop it.")
        self.app.push_screen(ConfirmScreen("Execute the plan?", body), self._confirmed)

    def _confirmed(self, yes: bool | None) -> None:
        if not yes:
            self.status.ok("execution cancelled: nothing moved")
            return
        self.console.live_samples.clear()
        self._last_plot = 0.0
        self.query_one("#exec-outcome", Static).update("")
        on_sample = self.console.telemetry_sink(self)
        self.console.moving = True
        if not self.run_blocking("execute",
                                 lambda: MotionDone("execute", self.session.execute(on_sample)),
                             "executing … SPACE stops the wrist"):
            self.console.moving = False

    def action_next_plot(self) -> None:
        self.plot_kind = (self.plot_kind + 1) % 2
        self.draw_plot()

    # ------------------------------------------------------------------ live
    def on_telemetry(self, message: Telemetry) -> None:
        message.stop()
        self.show_sample(message.sample)
        if message.sample.t - self._last_plot >= PLOT_EVERY_S:
            self._last_plot = message.sample.t
            self.draw_plot()

    def show_sample(self, smp: Any) -> None:
        t = self.query_one("#joints", DataTable)
        cols = list(t.columns.keys())
        for i in range(3):
            vals = (f"{smp.reference_deg[i]:7.2f}°", f"{smp.measured_deg[i]:7.2f}°",
                    f"{smp.velocity_degps[i]:6.1f}°/s",
                    f"{smp.measured_deg[i] - smp.predicted_deg[i]:+5.2f}°")
            for c, v in zip(cols[1:], vals, strict=True):
                t.update_cell(str(i), c, v)
        total = max(self.session.motion_total_s, 1e-9)
        self.query_one("#exec-clock", Static).update(Content(
            f"{smp.phase}: {smp.t:5.2f} s done\n{max(total - smp.t, 0):5.2f} s to go"))
        self.query_one("#exec-progress", ProgressBar).update(progress=min(100, 100 * smp.t / total))

    def draw_plot(self) -> None:
        samples = list(self.console.live_samples)
        view = self.query_one("#exec-plot", PlotView)
        if len(samples) < 2:
            return
        t = np.array([s.t for s in samples])
        if self.plot_kind == 0:
            series = joint_series("θ*", [s.reference_deg for s in samples], faint=True)
            series += joint_series("θ", [s.measured_deg for s in samples])
            view.plot("reference θ* (dots), measured θ [deg]", t, series)
        else:
            series = joint_series("model ", [s.predicted_velocity_degps for s in samples],
                                  faint=True)
            series += joint_series("KF ", [s.velocity_degps for s in samples])
            view.plot("velocity dθ/dt [deg/s]: Kalman filter, model (dots)", t, series)

    # ------------------------------------------------------------------ outcome
    def handle_done(self, outcome: Outcome) -> None:
        if not isinstance(outcome, MotionDone):
            return
        result = outcome.result
        self.console.moving = False
        self.console.after_motion(result)
        if self.console.live_samples:
            self.show_sample(self.console.live_samples[-1])  # telemetry is throttled: the last
        self.draw_plot()
        self.query_one("#exec-outcome", Static).update(Content(outcome_text(result)))
        if result.ok:
            self.status.ok(f"completed: {result.message}. Press 6 to look at the log")
        else:
            self.status.error(f"STOPPED: {result.message}")

    def handle_failed(self, op: str, message: str) -> None:
        if op == "execute":
            self.console.moving = False


def outcome_text(result: Any) -> str:
    head = "COMPLETED" if result.ok else "STOPPED"
    lines = [f"{head} (exit code {int(result.exit_code)}): {result.message}"]
    if result.final_deg is not None:
        lines.append(f"final θ = {fmt_deg(result.final_deg)}")
    rms = result.stats.tracking_rms_deg
    if result.stats.samples and np.isfinite(rms):
        lines.append(f"tracking error RMS {rms:.3f}°")
    if result.realtime:
        flag = "" if result.realtime_granted else "  (NOT real-time: timing may suffer under load)"
        lines.append(f"servo loop: {result.realtime}{flag}")
    lines.append(f"log: {result.log_dir}")
    return "\n".join(lines)
