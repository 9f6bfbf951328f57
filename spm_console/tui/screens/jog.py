"""Live jog (from step 5): the wrist follows a target the arrow keys move, live.

The runtime's live following (``session.following.follow``,
:meth:`~spm_console.services.session_follow.FollowTools.follow`) runs in a worker thread:
it re-plans every servo period inside one region of the workspace (P, a region of its
cover, or a region the runtime grows around a start on the boundary) toward the latest
target and streams only references it verified; a target outside every region is projected
into the wrist's region (clamped). Each key press moves the target by the chosen step — in
roll/pitch/yaw from home (IK in the home working mode) or per joint — and goes to the runtime
at once, from the :class:`~spm_console.tui.screens.jog_target.TargetSender` thread. The 3D view
shows the target as the ghost and the measured pose solid. esc (or j) ends the jog: the wrist
settles on the last target and the run completes (its log is in step 6). SPACE E-stops.

No deadman on the target: the console itself is the source, so silence means "hold this
target", which following does anyway; a console that dies or hangs is caught by the motion
process's client-heartbeat deadman, which holds the wrist. Degrees, seconds.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Vertical
from textual.content import Content
from textual.widgets import Static

from spm_console.config.models import servo_limits_deg, servo_tick_deg
from spm_console.core.kinematics.rotations import matrix_rpy
from spm_console.core.planning.follow.tolerance import FOLLOW_TOL_DEG
from spm_console.core.polytope.region import Region
from spm_console.errors import SpmError
from spm_console.formatting import fmt_deg
from spm_console.motion.follow.regions import follow_regions, follow_start
from spm_console.motion.sample import Sample
from spm_console.services.session import Session
from spm_console.tui.messages import FollowDone, Outcome, Telemetry, WorkspaceLoaded
from spm_console.tui.screens.base import StepScreen
from spm_console.tui.screens.jog_target import JogTarget, TargetSender
from spm_console.tui.widgets.plot import PlotView, joint_series

F = NDArray[np.float64]

#: Live plot redraw interval, s.
PLOT_EVERY_S = 0.5
#: IK of the orientation found by FK must give back θ within this, deg (else that θ is in
#: another working mode: no roll/pitch/yaw jogging from it).
RPY_ROUND_TRIP_DEG = 1e-3
#: What the run log calls the console's jog (its ``source``).
JOG_SOURCE = "console live jog"

KEYS_TEXT = "←→ ↑↓ PgUp PgDn move the target · +/- step · m mode · esc ends · SPACE stops"

@dataclass(frozen=True)
class JogFailure:
    """Why a jog was refused or failed."""

    reason: str
    moved: bool
    """Whether the following had started (the wrist may have moved)."""


JogResult = FollowDone | JogFailure | None
"""What the jog screen hands back: the ended run, why it could not start or failed, or
nothing."""


def rpy_of(session: Session, theta_deg: F) -> F | None:
    """Roll, pitch, yaw from home (deg) of the pose at θ (deg), when θ is that orientation's
    IK in the home working mode; None otherwise (or when FK fails)."""
    try:
        v = np.asarray(session.wrist.fk(theta_deg).v, float)
        R = np.linalg.solve(np.asarray(session.wrist.model.v_home, float), v).T  # v = v_home Rᵀ
        rpy = np.degrees(matrix_rpy(R))
        back = session.wrist.ik(rpy)
    except (SpmError, KeyError, ValueError, np.linalg.LinAlgError):
        return None
    if not np.all(np.isfinite(back)) or float(np.abs(back - theta_deg).max()) > RPY_ROUND_TRIP_DEG:
        return None
    return np.asarray(rpy, float)


def outside_deg(session: Session, theta_deg: F, regions: tuple[Region, ...] | None = None
                ) -> float:
    """How far θ (deg) lies outside every one of ``regions`` (those the follower plans in;
    None: the workspace region P) or the servo limits, deg (0 inside): the follower projects
    such a target into the wrist's region (clamped)."""
    th = np.asarray(theta_deg, float)
    lo, hi = servo_limits_deg(session.profile)
    over = float(max(0.0, np.max(lo - th), np.max(th - hi)))
    ws = session.wrist.workspace
    if regions is None:
        regions = () if ws is None else (ws.region,)
    if not regions:
        return over
    return max(over, min(float(r.violation_deg(th)) for r in regions))


def clamp_text(out_deg: float, in_p: bool = True) -> str:
    """Whether a target ``out_deg`` outside every region (or the servo limits) is projected;
    ``in_p``: whether it lies in P."""
    if out_deg > FOLLOW_TOL_DEG:
        return f"CLAMPED: {out_deg:.2f}° outside every region: the wrist stops at the edge"
    return "inside P: not clamped" if in_p else "outside P, inside the cover: not clamped"


def _vec(v: F | None) -> str:
    return "–" if v is None else fmt_deg(v)


class JogScreen(StepScreen):
    """Pushed over step 5 while the wrist jogs live; when it closes, ``on_end`` receives
    the :data:`JogResult`."""

    MODE = "execute"
    HELP_TITLE = "Live jog (from step 5)"
    HELP_NOTE = ("Each key press sends a new target at once; the wrist follows it inside the "
                 "workspace's regions (P and its cover). A target outside every region is "
                 "projected into the wrist's region (shown as CLAMPED); a key that would take "
                 "it farther out is refused. "
                 "esc or j ends the jog: the wrist settles on the last target and the run "
                 "completes (its log is in step 6). SPACE stops the wrist at once.")
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("left", "nudge(0, -1)", "Yaw or θ1 −/+", show=False, priority=True,
                key_display="←"),
        Binding("right", "nudge(0, 1)", "Yaw or θ1 −/+", show=False, priority=True,
                key_display="→"),
        Binding("up", "nudge(1, 1)", "Pitch or θ2 +/−", show=False, priority=True,
                key_display="↑"),
        Binding("down", "nudge(1, -1)", "Pitch or θ2 +/−", show=False, priority=True,
                key_display="↓"),
        Binding("pageup", "nudge(2, 1)", "Roll or θ3 +/−", show=False, priority=True,
                key_display="PgUp"),
        Binding("pagedown", "nudge(2, -1)", "Roll or θ3 +/−", show=False, priority=True,
                key_display="PgDn"),
        Binding("plus,equals_sign", "coarser", "Step+", key_display="+", priority=True),
        Binding("minus", "finer", "Step−", key_display="-", priority=True),
        Binding("m", "toggle_mode", "Mode", priority=True,
                tooltip="roll/pitch/yaw from home, or per joint"),
        Binding("escape", "end_jog", "End jog", key_display="esc", priority=True,
                tooltip="the wrist settles on the last target; the run completes"),
        Binding("j", "end_jog", "End jog", show=False, priority=True),
    ]

    DEFAULT_CSS = """
    JogScreen #jog-plot { height: 1fr; }
    JogScreen .jog-line { height: auto; }
    """

    def __init__(self, theta0_deg: F, on_end: Callable[[JogResult], None]) -> None:
        super().__init__()
        self._on_end = on_end
        self.theta0_deg = np.asarray(theta0_deg, float).copy()
        self.start_deg = self.theta0_deg
        """Where the target starts: θ0, or just inside the grid when the wrist stands a servo
        tick beyond it (:func:`~spm_console.motion.follow.regions.follow_start`)."""
        """Where the jog starts: the target before any key (deg)."""
        self.target: JogTarget | None = None
        """The live target (None until the first cycle of the following ran)."""
        self._prepared: JogTarget | None = None
        """Made by the worker before the following starts; live at the first telemetry."""
        self.sender: TargetSender | None = None
        self.phase = "preparing"
        """preparing (nothing moves yet) → starting → live → ending → done."""
        self._end_asked = False
        self._last_plot = -1.0
        self.last_sample: Sample | None = None
        self.regions: tuple[Region, ...] | None = None
        """The regions the follower plans in (found while preparing; None before)."""

    def compose_body(self) -> ComposeResult:
        with Vertical(classes="body"):
            yield Static("Live jog: starting the following …", id="jog-head", markup=False,
                         classes="jog-line")
            yield Static(id="jog-mode", markup=False, classes="jog-line")
            yield Static(id="jog-target", markup=False, classes="jog-line")
            yield Static(id="jog-measured", markup=False, classes="jog-line")
            yield Static(id="jog-clamp", markup=False, classes="jog-line")
            yield Static(KEYS_TEXT, id="jog-keys", markup=False, classes="jog-line result")
            yield PlotView(id="jog-plot")

    def on_mount(self) -> None:
        """First the workspace (P, to tell the operator when a target gets clamped) and the
        start pose's orientation, while nothing moves; then the following."""
        s, th0 = self.session, self.theta0_deg

        def prepare() -> Outcome:
            ws = s.wrist.ensure_workspace()
            # the runtime's own choice (it repeats it from the measured start): refused here,
            # with the reason, before anything moves
            # (a wrist a servo tick beyond the grid's edge starts just inside it)
            # — and the target starts there too, not where no region reaches
            start = follow_start(ws, th0, s.profile.safety.approach_tolerance_deg,
                                 servo_tick_deg(s.profile))
            self.regions = regions = follow_regions(ws, start).regions
            self.start_deg = start
            self._prepared = JogTarget(start, rpy_of(s, start), s.wrist.ik,
                                       lambda t: outside_deg(s, t, regions))
            return WorkspaceLoaded()

        self.console.moving = True  # the steps stay locked from here to the end of the run
        if not self.run_blocking("jog-prepare", prepare, "live jog: loading the workspace …"):
            self.console.moving = False

    def _start_following(self) -> None:
        s, th0 = self.session, self.start_deg
        self.phase = "starting"
        self.sender = TargetSender(s.following.set_target, s.following.end_follow)
        on_sample = self.console.telemetry_sink(self)
        self.console.live_samples.clear()
        self.console.moving = True
        if not self.run_blocking("jog", lambda: FollowDone(s.following.follow(
                initial_deg=th0, deadman_s=None, on_sample=on_sample, source=JOG_SOURCE)),
                "live jog: starting … SPACE stops the wrist"):
            self.console.moving = False

    def on_unmount(self) -> None:
        if self.sender is not None:
            self.sender.close(wait_s=0.5)

    # ------------------------------------------------------------------ keys
    def _usable(self) -> JogTarget | None:
        if self.target is None or self.sender is None or self.phase != "live":
            self.status.error({"preparing": "wait: the workspace is loading",
                               "starting": "wait: the following is starting",
                               "ending": "the jog is ending: the wrist settles on the last target",
                               "done": "the jog has ended"}.get(self.phase, self.phase))
            return None
        return self.target

    def action_nudge(self, slot: int, sign: int) -> None:
        tgt = self._usable()
        if tgt is None:
            return
        why = tgt.nudge(slot, sign)
        if why:
            self.status.error(why)
            self.app.bell()
            return
        self._send(tgt)

    def _send(self, tgt: JogTarget) -> None:
        assert self.sender is not None
        self.sender.put(tgt.theta_deg)
        self.console.view.show_target(tgt.theta_deg)
        self.show_target()
        self.status.ok(f"target θ = {fmt_deg(tgt.theta_deg)} sent")

    def action_coarser(self) -> None:
        tgt = self._usable()
        if tgt is not None:
            if not tgt.coarser():
                self.status.error(f"{tgt.step_deg:g}° is the largest step")
            self.show_target()

    def action_finer(self) -> None:
        tgt = self._usable()
        if tgt is not None:
            if not tgt.finer():
                self.status.error(f"{tgt.step_deg:g}° is the smallest step")
            self.show_target()

    def action_toggle_mode(self) -> None:
        tgt = self._usable()
        if tgt is None:
            return
        why = tgt.toggle_mode(lambda th: rpy_of(self.session, th))
        if why:
            self.status.error(why)
        self.show_target()

    def action_end_jog(self) -> None:
        if self.phase in ("done", "preparing"):  # nothing moves: just close
            self.console.moving = False
            self._leave(None)
            return
        if self.phase == "ending":
            self.status.busy("ending: the wrist settles on the last target … SPACE stops it")
            return
        self._end_asked = True
        if self.phase == "live":
            self._end()
        else:
            self.status.busy("the jog ends as soon as the following has started …")

    def _end(self) -> None:
        self.phase = "ending"
        if self.sender is not None:
            self.sender.end()
        self.query_one("#jog-head", Static).update(
            Content("Live jog: ending — the wrist settles on the last target …"))
        self.status.busy("ending: the wrist settles on the last target … SPACE stops it")

    # ------------------------------------------------------------------ display
    def show_target(self) -> None:
        tgt = self.target
        if tgt is None:
            return
        self.query_one("#jog-mode", Static).update(Content(tgt.describe()))
        rpy = "" if tgt.rpy_deg is None else f"   roll/pitch/yaw = {fmt_deg(tgt.rpy_deg)}"
        self.query_one("#jog-target", Static).update(Content(
            f"target:      θ = {fmt_deg(tgt.theta_deg)}{rpy}\n"
            f"             {clamp_text(tgt.outside_deg, self._in_p(tgt.theta_deg))}"))

    def on_telemetry(self, message: Telemetry) -> None:
        message.stop()
        smp: Sample = message.sample
        self.last_sample = smp
        if self.phase == "starting" and self._prepared is not None:
            self._go_live(self._prepared)
        looped = smp.target_deg
        self.query_one("#jog-measured", Static).update(Content(
            f"measured:    θ = {_vec(smp.measured_deg if smp.read_ok else None)}   "
            f"θ* = {_vec(smp.reference_deg)}"))
        if looped is not None and smp.target_clamp_deg is not None:  # the follower's own word
            self.query_one("#jog-clamp", Static).update(Content(
                f"in the loop: θ = {fmt_deg(looped)} (the target this cycle)\n"
                f"             {clamp_text(smp.target_clamp_deg, self._in_p(looped))}"))
        if smp.t - self._last_plot >= PLOT_EVERY_S:
            self._last_plot = smp.t
            self.draw_plot()

    def _go_live(self, tgt: JogTarget) -> None:
        self.target = tgt
        self.phase = "live"
        self.console.view.show_target(tgt.theta_deg)
        self.query_one("#jog-head", Static).update(Content(
            "Live jog: the wrist follows the target (re-planned each period in a region)"))
        self.show_target()
        if self._end_asked:
            self._end()
        else:
            self.status.ok("live: move the target with the arrow keys")

    def _in_p(self, theta_deg: F) -> bool:
        ws = self.session.wrist.workspace
        return ws is None or bool(ws.region.contains(np.asarray(theta_deg, float),
                                                     tol=FOLLOW_TOL_DEG))

    def draw_plot(self) -> None:
        samples = [s for s in list(self.console.live_samples) if s.target_deg is not None]
        if len(samples) < 2:
            return
        t = np.array([s.t for s in samples])
        series = joint_series("target ", [s.target_deg for s in samples], faint=True)
        series += joint_series("θ", [s.measured_deg for s in samples])
        self.query_one("#jog-plot", PlotView).plot("target (dots), measured θ [deg]", t, series)

    # ------------------------------------------------------------------ the end
    def handle_done(self, outcome: Outcome) -> None:
        if isinstance(outcome, WorkspaceLoaded):
            if self.phase == "preparing":
                self._start_following()
            return
        if not isinstance(outcome, FollowDone):
            return
        self.phase = "done"
        self.console.moving = False
        self.console.after_motion(outcome.outcome.execution)
        self._leave(outcome)

    def handle_failed(self, op: str, message: str) -> None:
        if op not in ("jog", "jog-prepare"):
            return
        moved = self.phase not in ("preparing", "starting")
        self.phase = "done"
        self.console.moving = False
        self._leave(JogFailure(message, moved))

    def _leave(self, result: JogResult) -> None:
        """Close (with the help or the palette opened over it) and hand ``result`` back."""
        self.console.view.show_target(None)
        if self.sender is not None:
            self.sender.close(wait_s=0.5)
        if self.app.screen is not self:
            self.pop_until_active()
        self.dismiss(None)
        self._on_end(result)

    def refresh_view(self) -> None:
        if self.is_attached and self.app.screen is self:
            super().refresh_view()
