"""Step 5: execute the plan — confirmation, live θ / velocity / tracking per joint, the
servo loop's timing so far, plots, elapsed and remaining time, the E-stop, then the outcome
and the log path. ``j`` starts the live jog (:mod:`.jog`): the wrist follows a target the
arrow keys move."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal, Vertical
from textual.content import Content
from textual.widgets import DataTable, ProgressBar, Static

from spm_console.formatting import fmt_deg
from spm_console.motion.sample import Sample
from spm_console.tui.messages import FollowDone, MotionDone, Outcome, PreviewDone, Telemetry
from spm_console.tui.screens.base import StepScreen
from spm_console.tui.screens.execute_preview import draw_preview, preview_lines, still_valid
from spm_console.tui.screens.jog import JogFailure, JogResult, JogScreen
from spm_console.tui.screens.plan_words import KIND_WORDS
from spm_console.tui.widgets.confirm import LongConfirm
from spm_console.tui.widgets.loop_timing import LiveTiming, LoopTiming
from spm_console.tui.widgets.plot import PlotView, joint_series

if TYPE_CHECKING:
    from spm_console.services.preview import Preview

#: Live plot redraw interval, s (telemetry itself arrives every Ts, coalesced).
PLOT_EVERY_S = 0.5

NO_REPLY = "no reply"
"""Shown for a joint angle the cycle's read did not return (after its retries)."""

JOINT_COLUMNS = ("joint", "reference θ*", "measured θ", "dθ/dt (KF)",
                 "measured −\nmodel", "reference −\nmeasured")
"""Live table headers (two lines: the table fits 80 columns)."""


def _last_read(samples: list[Sample]) -> Sample:
    """The last sample whose position read succeeded (after a run the table shows where the
    wrist ended, not a final cycle's lost reply), else the last one."""
    return next((s for s in reversed(samples) if s.read_ok), samples[-1])


def _angle(x: float, fmt: str) -> str:
    return f"{x:{fmt}}°" if math.isfinite(x) else NO_REPLY


def _diff(a: float, b: float) -> str:
    d = a - b
    return f"{d:+5.2f}°" if math.isfinite(d) else "–"


class ExecuteScreen(StepScreen):
    MODE = "execute"
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("x", "execute", "Execute",
                tooltip="previews the run on the twin first, then asks"),
        Binding("v", "preview", "Preview",
                tooltip="the run on the wrist's twin in simulated time: nothing moves"),
        Binding("p", "next_plot", "Plot"),
        Binding("j", "jog", "Live jog",
                tooltip="the wrist follows a target the arrow keys move (homed only)"),
    ]

    DEFAULT_CSS = """
    ExecuteScreen #exec-clock-row { height: 1; }
    ExecuteScreen #exec-clock { width: auto; padding: 0 2 0 0; }
    ExecuteScreen #exec-timing { height: auto; }
    ExecuteScreen #exec-preview { display: none; }
    """

    def __init__(self) -> None:
        super().__init__()
        self.plot_kind = 0
        self._last_plot = 0.0
        self.timing: LiveTiming | None = None
        """The running execution's timing (None before the first execution)."""
        self._fed = 0
        """How many of ``console.live_samples`` the timing has taken in."""
        self.preview: Preview | None = None
        """The last preview (:mod:`.execute_preview`)."""
        self._confirm_after_preview = False

    def compose_body(self) -> ComposeResult:
        with Vertical(classes="body"):
            yield Static(id="exec-plan", markup=False)
            yield Static(id="exec-preview", markup=False)
            yield DataTable(id="joints", cursor_type="none", header_height=2)
            with Horizontal(id="exec-clock-row"):
                yield Static(id="exec-clock", markup=False)
                yield ProgressBar(total=100, id="exec-progress", show_eta=False)
            yield Static("servo loop timing: shown while a plan executes", id="exec-timing",
                         markup=False)
            yield Static(id="exec-outcome", markup=False, classes="result")
            yield PlotView(id="exec-plot")

    def on_mount(self) -> None:
        t = self.query_one("#joints", DataTable)
        t.add_columns(*JOINT_COLUMNS)
        for i in range(3):
            t.add_row(str(i + 1), *("-" for _ in JOINT_COLUMNS[1:]), key=str(i))
        self.refresh_view()

    def refresh_view(self) -> None:
        super().refresh_view()
        s = self.session
        if s.plans.plan is None:
            text = "No plan yet: press 4 to plan a motion."
        else:
            p = s.plans.plan
            text = (f"Plan: {KIND_WORDS.get(p.kind, p.kind)} {fmt_deg(p.reference_deg[0])} → "
                    f"{fmt_deg(p.reference_deg[-1])}, {p.duration_s:.2f} s, on the {s.bus_label}"
                    + ("" if s.homed else "   (not homed: press 1, then h)"))
        self.query_one("#exec-plan", Static).update(Content(text))
        if self.preview is not None and self.preview.plan is not s.plans.plan:
            self._drop_preview()  # another plan: its preview no longer says anything

    def _drop_preview(self) -> None:
        """Forget the preview shown, its panel and its plot (the plan it was of is gone)."""
        self.preview = None
        self.query_one("#exec-preview", Static).display = False
        self.query_one("#exec-plot", PlotView).plot("", [], [])

    def _can_move(self) -> bool:
        """A plan, a homed wrist and nothing running (else refused with the reason)."""
        s = self.session
        if s.plans.plan is None:
            self.status.refused("no plan: press 4 and solve one first")
            return False
        if s.bus is None or not s.homed:
            self.status.refused(_not_ready(s.bus is not None))
            return False
        if self.busy_op or self.console.moving:
            self.status.error("busy: a motion is already running")
            return False
        return True

    def action_preview(self, then_confirm: bool = False) -> None:
        """Run the plan on the wrist's twin in simulated time (nothing moves); show it."""
        if not self._can_move():
            return
        from spm_console.services.preview import preview_in_session

        self._confirm_after_preview = then_confirm
        self._show_preview_text("Preview: the run on the wrist's twin, in simulated time …")
        self.run_blocking("preview", lambda: PreviewDone(preview_in_session(self.session)),
                          "previewing the run on the twin (simulated time; nothing moves) …")

    def action_execute(self) -> None:
        """Preview the run (unless the last preview is of this plan from here), then ask."""
        if not self._can_move():
            return
        s = self.session
        pv = self.preview
        if pv is not None and s.plans.plan is not None and still_valid(pv, s.plans.plan, s.theta_deg):
            self._ask(pv)
        else:
            self.action_preview(then_confirm=True)

    def _ask(self, pv: Preview) -> None:
        s = self.session
        p = s.plans.plan
        if p is None:
            return
        here = fmt_deg(s.theta_deg) if s.theta_deg is not None else "unknown"
        kind = "minimum-time" if p.kind == "mintime" else KIND_WORDS.get(p.kind, p.kind)
        body = (f"The wrist moves on the {s.bus_label}: {kind} plan of "
                f"{p.duration_s:.2f} s from {fmt_deg(p.reference_deg[0])} to "
                f"{fmt_deg(p.reference_deg[-1])} (now at {here}; a straight approach move at "
                f"≤ {s.profile.safety.home_speed_degps:g}°/s comes first if needed).\n"
                "Press SPACE at any time to stop it.\n\n" + "\n".join(preview_lines(pv)))
        title = ("Execute the plan?" if pv.run.execution.ok else
                 "Execute the plan? Its preview STOPPED on the twin")
        self.app.push_screen(LongConfirm(title, body), self._confirmed)

    def _confirmed(self, yes: bool | None) -> None:
        if not yes:
            self.status.ok("execution cancelled: nothing moved")
            return
        self.console.live_samples.clear()
        self._last_plot = 0.0
        self.timing = LiveTiming(self.session.profile.servo.ts_s)
        self._fed = 0
        self.query_one("#exec-timing", Static).update(
            Content("servo loop timing: waiting for the first cycle …"))
        self.query_one("#exec-outcome", Static).update("")
        on_sample = self.console.telemetry_sink(self)
        self.console.moving = True
        plans = self.session.plans
        if not self.run_blocking("execute",
                                 lambda: MotionDone("execute", self.session.execute(
                                     plans.require(), on_sample, source=plans.source)),
                             "executing … SPACE stops the wrist"):
            self.console.moving = False

    def action_jog(self) -> None:
        """Start the live jog from where the wrist is (homed only, nothing else moving)."""
        s = self.session
        if s.bus is None or not s.homed or s.theta_deg is None:
            self.status.refused(_not_ready(s.bus is not None))
            return
        if self.busy_op or self.console.moving:
            self.status.error("busy: a motion is already running")
            return
        here = np.asarray(s.theta_deg, float)
        home = np.asarray(s.profile.home.theta_deg, float)
        # near home (the homing's own tolerance), start from home itself: roll/pitch/yaw 0
        if float(np.abs(here - home).max()) <= s.profile.safety.approach_tolerance_deg:
            here = home
        self.query_one("#exec-outcome", Static).update("")
        self.app.push_screen(JogScreen(here, self._jog_ended))

    def _jog_ended(self, result: JogResult) -> None:
        """The jog screen closed: the run's outcome (or why it did not run) shows here."""
        self.refresh_view()
        if isinstance(result, JogFailure):
            # kept on the screen (the status line is the next action's)
            head = "LIVE JOG FAILED" if result.moved else "LIVE JOG REFUSED (nothing moved)"
            self.query_one("#exec-outcome", Static).update(Content(f"{head}: {result.reason}"))
            self.status.error(f"live jog: {result.reason}")
            return
        if not isinstance(result, FollowDone):
            self.status.ok("live jog closed before it started: nothing moved")
            return
        ex, st = result.outcome.execution, result.outcome.stats
        # the progress, clock and loop timing shown were the last plan's: now the jog's run,
        # which has no planned length (a stopped jog read "0%"): the bar is hidden until a
        # plan runs again
        self._progress(None)
        self.query_one("#exec-clock", Static).update(Content(
            f"live jog: {ex.stats.duration_s:.2f} s" if ex.ok or ex.stats.stop is None else
            f"live jog stopped at {ex.stats.stop.detected_t:.2f} s"))
        self.query_one("#exec-timing", Static).update(Content(
            LoopTiming.of_run(ex.stats).text() if ex.stats.samples else
            "servo loop timing: no cycle ran"))
        text = outcome_text(ex)
        if st is not None:
            text += (f"\nlive jog: {st.adopted} of {st.solves} re-plans used, "
                     f"{st.misses} missed, {st.refused} refused, "
                     f"{st.clamped} periods with the target clamped into its region")
        self.query_one("#exec-outcome", Static).update(Content(text))
        if self.console.live_samples:  # the jog's last sample and its plot
            self.show_sample(_last_read(self.console.live_samples), clock=False)
            self.draw_plot()
        if ex.ok:
            self.status.ok(f"live jog completed: {ex.message}. Press 6 to look at the log")
        else:
            self.status.error(f"live jog STOPPED: {ex.message}")

    def action_next_plot(self) -> None:
        self.plot_kind = (self.plot_kind + 1) % 2
        self.draw_plot()

    # ------------------------------------------------------------------ live
    def on_telemetry(self, message: Telemetry) -> None:
        message.stop()
        self.show_sample(message.sample)
        self.update_timing()
        if message.sample.t - self._last_plot >= PLOT_EVERY_S:
            self._last_plot = message.sample.t
            self.draw_plot()

    def update_timing(self) -> None:
        """Take in the samples received since the last update; show the timing so far."""
        if self.timing is None:  # telemetry of a motion this screen did not start
            self.timing = LiveTiming(self.session.profile.servo.ts_s)
        samples = self.console.live_samples
        n = len(samples)  # appended by the telemetry thread meanwhile: read up to here
        if n < self._fed:  # cleared by another motion (homing)
            self._fed = 0
        self.timing.add(samples[self._fed:n])
        self._fed = n
        self.query_one("#exec-timing", Static).update(Content(self.timing.timing().text()))

    def show_sample(self, smp: Sample, clock: bool = True) -> None:
        t = self.query_one("#joints", DataTable)
        cols = list(t.columns.keys())
        for i in range(3):
            ref, meas = float(smp.reference_deg[i]), float(smp.measured_deg[i])
            vals = (_angle(ref, "7.2f"), _angle(meas, "7.2f"),
                    f"{smp.velocity_degps[i]:6.1f}°/s",
                    _diff(meas, float(smp.predicted_deg[i])), _diff(ref, meas))
            for c, v in zip(cols[1:], vals, strict=True):
                t.update_cell(str(i), c, v)
        if not clock:
            return
        total = max(self.session.motion_total_s, 1e-9)
        self.query_one("#exec-clock", Static).update(Content(
            f"{smp.phase}: {smp.t:5.2f} s done, {max(total - smp.t, 0):5.2f} s to go"))
        self._progress(min(100, 100 * smp.t / total))

    def _progress(self, percent: float | None) -> None:
        """The plan's progress bar at ``percent``; hidden for None (a run without a planned
        length: a live jog)."""
        bar = self.query_one("#exec-progress", ProgressBar)
        bar.display = percent is not None
        if percent is not None:
            bar.update(progress=percent)

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
    def _show_preview_text(self, text: str) -> None:
        """The preview's panel under the plan (hidden before the first preview)."""
        panel = self.query_one("#exec-preview", Static)
        panel.update(Content(text))
        panel.display = True

    def show_preview(self, pv: Preview) -> None:
        self.preview = pv
        self._show_preview_text("\n".join(preview_lines(pv)))
        draw_preview(self.query_one("#exec-plot", PlotView), pv)

    def handle_done(self, outcome: Outcome) -> None:
        if isinstance(outcome, PreviewDone):
            self.show_preview(outcome.preview)
            if self._confirm_after_preview and self._can_move():
                self._ask(outcome.preview)
            elif outcome.preview.run.execution.ok:
                self.status.ok("preview: the run completes on the twin; x executes it")
            else:
                self.status.error("preview: the run STOPS on the twin "
                                  f"({outcome.preview.run.execution.message})")
            return
        if not isinstance(outcome, MotionDone):
            return
        result = outcome.result
        self.console.moving = False
        self.console.after_motion(result)
        if self.console.live_samples:  # (telemetry is throttled: the last one sent)
            self.show_sample(_last_read(self.console.live_samples))
        if result.ok:
            self._progress(100)
            self.query_one("#exec-clock", Static).update(
                Content(f"done: servo loop {result.stats.duration_s:.2f} s"))
        elif result.stats.stop is not None:
            self.query_one("#exec-clock", Static).update(
                Content(f"stopped at {result.stats.stop.detected_t:.2f} s"))
        self.draw_plot()
        if result.stats.samples:  # every cycle, counted where the loop ran
            self.query_one("#exec-timing", Static).update(
                Content(LoopTiming.of_run(result.stats).text()))
        else:
            self.query_one("#exec-timing", Static).update(
                Content("servo loop timing: no cycle ran"))
        self.query_one("#exec-outcome", Static).update(Content(outcome_text(result)))
        self.status.run_result(f"completed: {result.message}. Press 6 to look at the log"
                               if result.ok else f"STOPPED: {result.message}", result)

    def handle_failed(self, op: str, message: str) -> None:
        if op == "execute":
            self.console.moving = False
        elif op == "preview":
            self._show_preview_text(f"Preview failed (nothing moved): {message}")


def _not_ready(connected: bool) -> str:
    """Why nothing may move yet, and what to press."""
    if connected:
        return "the wrist is not homed: press 1, then h to home it"
    return "the wrist is not connected: press 1, then c to connect and h to home it"


def outcome_text(result: Any) -> str:
    head = "COMPLETED" if result.ok else "STOPPED"
    lines = [f"{head} (exit code {int(result.exit_code)}): {result.message}"]
    if result.final_deg is not None:
        lines.append(f"final θ = {fmt_deg(result.final_deg)}")
    if result.settle is not None and result.settle.text():
        lines.append(result.settle.text())
    rms = result.stats.tracking_rms_deg
    if result.stats.samples and np.isfinite(rms):
        lines.append(f"tracking error RMS {rms:.3f}°")
    if result.stats.model is not None:
        lines.append(result.stats.model.text().replace(
            "spm-console identify --experiment --out NEW.toml", "step 1 (F1), i: identify the servos"))
    if result.realtime:
        flag = "" if result.realtime_granted else "  (NOT real-time: timing may suffer under load)"
        lines.append(f"servo loop: {result.realtime}{flag}")
    lines.append(f"log: {result.log_dir}")
    return "\n".join(lines)
