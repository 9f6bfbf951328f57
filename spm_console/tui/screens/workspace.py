"""Step 3: the workspace — load it from the cache (or build it with a progress bar; ``c``
cancels a build at its next progress report), its counts and region P, and a pointwise
check of θ."""

from __future__ import annotations

import functools
import threading
from typing import Any, ClassVar

import numpy as np
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Vertical
from textual.content import Content
from textual.widgets import Input, ProgressBar, Static

from spm_console.errors import BadInputError, BuildCancelledError
from spm_console.formatting import fmt_deg
from spm_console.tui.messages import Failed, Outcome, Progress, ThetaChecked, WorkspaceLoaded
from spm_console.tui.screens.base import StepScreen
from spm_console.tui.widgets.angles import AnglesInput
from spm_console.tui.widgets.confirm import ConfirmScreen
from spm_console.tui.widgets.rules import THETA_NAMES, default_theta_deg, theta_rules

STAGES = {"fk": "FK over the grid", "links": "link distances", "region": "convex region P",
          "cover": "region cover",
          "done": "done"}


def workspace_text(ws: Any, info: Any) -> str:
    c = ws.counts()
    lo, hi = ws.range_deg()
    region = ws.region
    span = region_box(region)
    if info.hit:
        how = f"loaded from the cache ({info.path})"  # its time is a benchmark, not news
    else:
        how = f"built in {info.build_seconds:.1f} s ({info.rebuilt_because}); cached at {info.path}"
        if info.write_error:
            how += f" — NOT saved: {info.write_error}"
    lines = [
        how,
        f"grid         θ ∈ [{lo:g}, {hi:g}]° step {ws.step_deg:g}°: {c['nodes']} nodes",
        f"feasible     {c['feasible']}  (home-connected, ζ ≥ {ws.zeta_min:g}, links ≥ "
        f"{ws.min_distance_mm:g} mm apart)",
        f"singular     {c['singular']}   colliding {c['colliding']}   unreached "
        f"{c['unreached']}   disconnected {c['disconnected']}",
        f"region P     {region.halfspaces} half-spaces, covers {_pct(ws.coverage())} of the "
        "feasible nodes",
    ]
    if ws.cover is not None:
        n = ws.cover.size
        lines.append(f"cover        {n} region{'s' if n != 1 else ''} (P first) hold{'s' if n == 1 else ''} "
                     f"{_pct(ws.cover.covered)} of the feasible nodes; plans cross them")
    if span is not None:
        lines.append("P spans      " + "  ".join(
            f"θ{i + 1} ∈ [{span[0][i]:.1f}, {span[1][i]:.1f}]°" for i in range(3)))
    return "\n".join(lines)


def _pct(fraction: float) -> str:
    """A coverage in whole percent, rounded down. The regions' planes come from numerical
    solvers whose last bits depend on the machine's BLAS kernel, and that moves a coverage
    by about 0.1 %: a decimal would read differently on another CPU."""
    return f"{int(100 * fraction)}%"


@functools.lru_cache(maxsize=4)
def _box(A: bytes, b: bytes, n: int) -> tuple[np.ndarray, np.ndarray] | None:
    from scipy.optimize import linprog

    region_A = np.frombuffer(A).reshape(n, 3)
    region_b = np.frombuffer(b)
    lo, hi = np.zeros(3), np.zeros(3)
    for i in range(3):
        for sign, out in ((1.0, lo), (-1.0, hi)):
            c = np.zeros(3)
            c[i] = sign
            r = linprog(c, A_ub=region_A, b_ub=region_b, bounds=[(None, None)] * 3,
                        method="highs")
            if r.status != 0:
                return None
            out[i] = r.x[i]
    return lo, hi


def region_box(region: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """Bounding box of P (deg) by six small LPs (cached per region); None if unbounded."""
    A = np.ascontiguousarray(region.A, float)
    return _box(A.tobytes(), np.ascontiguousarray(region.b, float).tobytes(), A.shape[0])


def check_text(chk: Any) -> str:
    lines = [f"θ = {fmt_deg(chk.theta_deg)}: {chk.verdict}"]
    if chk.zeta is not None:
        lines.append(f"  ζ = {chk.zeta:.3f}, closest links {chk.min_link_mm:.1f} mm "
                     f"({chk.closest_pair})")
    lines.append(f"  feasible: {'yes' if chk.feasible else 'no'}   inside P: "
                 f"{'yes' if chk.in_region else 'no'} (slack {chk.region_slack_deg:+.2f}°)")
    if chk.reason:
        lines.append(f"  why: {chk.reason}")
    return "\n".join(lines)


class WorkspaceScreen(StepScreen):
    MODE = "workspace"
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("l", "load", "Load"),
        Binding("b", "rebuild", "Rebuild"),
        Binding("c", "cancel_build", "Cancel build",
                tooltip="stops a running build at its next progress report"),
        Binding("k", "check", "Check"),
        Binding("tab", "move_focus('next')", "Fields", priority=True),
        Binding("escape", "leave_field", "Leave", priority=True),
    ]

    def compose_body(self) -> ComposeResult:
        with Vertical(classes="body"):
            yield Static(id="ws-info", markup=False, classes="result")
            yield ProgressBar(total=100, id="ws-progress", show_eta=False)
            yield Static(id="ws-stage", markup=False)
            yield AnglesInput("Check θ (deg)", THETA_NAMES, default_theta_deg(self.session.profile),
                              rules=theta_rules(self.session.profile), id="check-theta")
            yield Static(id="ws-check", markup=False, classes="result")

    def on_mount(self) -> None:
        self.query_one("#ws-progress").display = False
        if self.session.wrist.workspace is None:
            self.action_load()
        else:  # already loaded (homing needs it: the runtime verifies every motion against it)
            self._ready()

    def _ready(self) -> None:
        self.show_workspace()
        info = self.session.wrist.cache_info
        self.status.ok("workspace ready (" + ("from the cache" if info is not None and info.hit else "built")
                       + "): press 4 to plan a motion")

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action == "cancel_build":  # in the footer only while a load runs
            return self.console.build_cancel is not None
        return True

    def action_load(self, force: bool = False) -> None:
        if self.busy_op:
            self.status.error(f"busy: {self.busy_op} is still running")
            return
        cancel = threading.Event()

        def progress(stage: str, fraction: float) -> None:
            # worker thread: a cancel lands at the build's next progress report
            if cancel.is_set():
                raise BuildCancelledError("workspace build cancelled by the operator")
            self.post_message(Progress(stage, fraction))

        bar = self.query_one("#ws-progress", ProgressBar)
        bar.update(progress=0)
        bar.display = True
        self.query_one("#ws-stage", Static).update("")

        def load() -> WorkspaceLoaded:
            self.session.wrist.load_workspace(progress, force=force)
            return WorkspaceLoaded()

        self.console.build_cancel = cancel
        self.run_blocking("load", load,
                          "rebuilding the workspace (c cancels) …" if force else
                          "loading the workspace (building it if there is no cache; "
                          "c cancels a build) …")
        self.refresh_bindings()

    def action_cancel_build(self) -> None:
        """Ask the running load/build to stop (at its next progress report)."""
        if not self.console.cancel_build():
            self.status.error("no workspace build is running")
            return
        self.status.busy("cancelling the build (it stops at its next progress report) …")

    def action_rebuild(self) -> None:
        body = ("Rebuild the workspace from scratch? It takes a while (the cache is replaced "
                "when done); the console stays usable meanwhile.")
        self.app.push_screen(ConfirmScreen("Rebuild the workspace?", body),
                             lambda yes: self.action_load(force=True) if yes else None)

    def on_progress(self, message: Progress) -> None:
        message.stop()
        self.query_one("#ws-progress", ProgressBar).update(progress=100 * message.fraction)
        self.query_one("#ws-stage", Static).update(
            Content(f"building: {STAGES.get(message.stage, message.stage)} "
                    f"({100 * message.fraction:.0f}%)"))

    def on_input_submitted(self, event: Input.Submitted) -> None:
        event.stop()
        self.action_check()

    def action_check(self) -> None:
        angles = self.query_one("#check-theta", AnglesInput)
        try:
            theta = angles.values()
        except BadInputError as exc:  # the field says why too; nothing is checked
            self.query_one("#ws-check", Static).update(Content(  # no verdict of older θ left
                f"No verdict: the check was refused.\n{exc.message}\n"
                "Next: fix the field marked invalid, then press k."))
            self.status.error(f"Check refused: {exc.message}. Fix the field, then press k.")
            return
        if self.session.wrist.workspace is None:
            self.status.error("no workspace yet: press l to load it")
            return
        self.run_blocking("check", lambda: ThetaChecked(self.session.wrist.check_theta(theta)),
                          f"checking θ = {fmt_deg(theta)} …")

    def on_failed(self, message: Failed) -> None:
        """A cancelled build is no error: it is said as such (the base handler, which
        reports errors, runs for every other failure)."""
        if message.op != "load":
            return
        cancel, self.console.build_cancel = self.console.build_cancel, None
        self.refresh_bindings()
        if cancel is None or not cancel.is_set():
            return
        message.stop()
        message.prevent_default()
        self.busy_op = ""
        self.console.build_cancel = None
        self.query_one("#ws-progress").display = False
        self.query_one("#ws-stage", Static).update(Content("build cancelled"))
        if self.session.wrist.workspace is not None:
            self.status.error("build cancelled: the workspace shown, loaded before, stays in "
                              "use (nothing was cached)")
        else:
            self.query_one("#ws-info", Static).update(Content(
                "No workspace: the build was cancelled (nothing was cached).\n"
                "Next: press l to load or build it."))
            self.status.error("build cancelled: no workspace (press l to load or build it)")
        self.refresh_view()

    def handle_done(self, outcome: Outcome) -> None:
        if isinstance(outcome, WorkspaceLoaded):
            self.console.build_cancel = None
            self.refresh_bindings()
            self.query_one("#ws-progress").display = False
            self.query_one("#ws-stage", Static).update("")
            self._ready()
        elif isinstance(outcome, ThetaChecked):
            result = outcome.check
            self.query_one("#ws-check", Static).update(Content(check_text(result)))
            if result.plannable:
                self.status.ok(result.verdict)
            else:
                self.status.error(result.verdict)
            if result.v is not None:
                self.console.view.show_target(np.asarray(result.theta_deg, float))

    def handle_failed(self, op: str, message: str) -> None:
        if op == "load":
            self.query_one("#ws-progress").display = False
            self.query_one("#ws-stage", Static).update("")
            if self.session.wrist.workspace is not None:  # what the screen shows is still in use
                self.status.error(f"{message} (the workspace shown, loaded before, stays in use)")
            else:
                self.query_one("#ws-info", Static).update(Content(
                    f"No workspace: {message}\nNext: press l to try again, or b to rebuild."))
        elif op == "check":  # the verdict this check would have replaced is cleared
            self.query_one("#ws-check", Static).update(Content(
                f"No verdict: the check failed.\n{message}\nNext: change θ, then press k."))
            self.status.error(f"check failed: {message}")

    def show_workspace(self) -> None:
        ws, info = self.session.wrist.workspace, self.session.wrist.cache_info
        if ws is None or info is None:
            return
        self.query_one("#ws-info", Static).update(Content(workspace_text(ws, info)))
