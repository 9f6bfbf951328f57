"""Step 4: plan a motion — start and goal (θ, orientation, home or current pose), MVN or
minimum time, solved in a worker; result table and plots."""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar

import numpy as np
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Horizontal, Vertical
from textual.content import Content
from textual.message import Message
from textual.widgets import Checkbox, Input, Label, Select, Static

from spm_console.errors import BadInputError, Issue, SpmError
from spm_console.services.wrist_service import PoseSpec
from spm_console.store.plan_file import save_plan
from spm_console.tui.messages import Failed, Outcome, PlanLoaded, PlanSaved, PlanSolved
from spm_console.tui.screens.base import StepScreen
from spm_console.tui.screens.plan_words import console_words, next_step, plan_text
from spm_console.tui.widgets.angles import AnglesInput
from spm_console.tui.widgets.ask_path import AskPathScreen
from spm_console.tui.widgets.checkbox import TickBox
from spm_console.tui.widgets.number import NumberRow
from spm_console.tui.widgets.plot import PlotView, joint_series
from spm_console.tui.widgets.rules import (
    THETA_NAMES,
    default_theta_deg,
    ik_check,
    intersample_rule,
    rpy_rules,
    steps_rule,
    theta_rules,
    vmax_rule,
)

POSE_KINDS = [("current pose", "current"), ("home", "home"), ("motor angles θ", "theta"),
              ("orientation r/p/y", "rpy")]
METHODS = [("minimum velocity norm (MVN)", "mvn"), ("minimum time", "mintime")]
METHOD_NAMES = {"mvn": "MVN", "mintime": "minimum-time"}
#: Default horizon N of an MVN plan (minimum time finds its own N).
DEFAULT_STEPS = 150
#: Default goal: the θ of the paper's eq. (32) example, deg.
PLOTS = ("positions", "velocities")
#: Period of the position read while the plan step shows "current pose", s.
POSE_EVERY_S = 0.5


class PoseRead(Message):
    """A background read of the servos' position ended (the session holds the result)."""


class PlanScreen(StepScreen):
    MODE = "plan"
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("s", "solve", "Solve"),
        Binding("p", "next_plot", "Plot"),
        Binding("w", "save", "Save"),
        Binding("o", "open", "Open plan"),
        Binding("tab", "move_focus('next')", "Fields", priority=True),
        Binding("escape", "leave_field", "Leave", priority=True),
    ]

    def __init__(self) -> None:
        super().__init__()
        self.plot_kind = 0
        self.solving_method = "mvn"
        self._solver_failed = False
        self._issue: Issue | None = None
        """The last failed solve was a solver's failure (not a refusal with a reason)."""
        self._reading = False
        self._typed: dict[str, list[str]] = {}
        """What the operator typed into the start / goal fields while they show the pose
        of "current pose" or "home" instead (given back when θ or r/p/y is chosen again)."""

    def compose_body(self) -> ComposeResult:
        prof = self.session.profile
        with Horizontal(classes="body"):
            with Vertical(id="plan-form"):
                yield Label("Start")
                yield Select(POSE_KINDS, value="current", allow_blank=False, id="start-kind")
                yield AnglesInput("", THETA_NAMES, prof.home.theta_deg,
                                  rules=theta_rules(prof, "start "), id="start-values")
                yield Label("Goal")
                yield Select(POSE_KINDS, value="theta", allow_blank=False, id="goal-kind")
                yield AnglesInput("", THETA_NAMES, default_theta_deg(self.session.profile),
                                  rules=theta_rules(prof, "goal "), id="goal-values")
                yield Label("Method")
                yield Select(METHODS, value="mvn", allow_blank=False, id="method")
                yield NumberRow("steps N", steps_rule(), str(DEFAULT_STEPS), id="steps")
                yield NumberRow("v_max °/s", vmax_rule(prof), f"{prof.limits.vmax_degps:g}",
                                id="vmax")
                yield NumberRow("intersample K", intersample_rule(), "1", id="intersample")
                yield TickBox("free first reference θ*(0)", False, id="free-first")
            with Vertical(id="plan-result"):
                yield Static(id="plan-text", markup=False, classes="result")
                yield PlotView(id="plan-plot")

    def on_mount(self) -> None:
        self.query_one("#plan-text", Static).update(Content(
            "Choose start and goal, then press s to solve (o opens a saved plan)."))
        self._recall()
        for which in ("start", "goal"):
            self._apply_kind(which)
        self._apply_method()
        if self.session.plans.plan is not None:
            self.show_plan()
        self.set_interval(POSE_EVERY_S, self._poll_pose)

    def _poll_pose(self) -> None:
        """Timer: while "current pose" is chosen and the step shows, read the servos (one
        read at a time, never while a solve runs or the wrist moves) and show the pose."""
        s = self.session
        if (self._reading or not self.is_active or self.busy_op or s.bus is None
                or self.console.moving or s.moving.is_set()
                or "current" not in (self._kind("start"), self._kind("goal"))):
            return
        self._reading = True
        self._read_pose()

    @work(thread=True, group="plan-pose", exit_on_error=False)
    def _read_pose(self) -> None:
        try:
            self.session.read_position()
        except SpmError:
            pass  # no reply this time: the last reading stays shown (step 1 shows the bus)
        finally:
            self.post_message(PoseRead())

    def on_pose_read(self, message: PoseRead) -> None:
        message.stop()
        self._reading = False
        for which in ("start", "goal"):
            self._show_pose(which)

    def _kind(self, which: str) -> object:
        return self.query_one(f"#{which}-kind", Select).value

    def on_select_changed(self, event: Select.Changed) -> None:
        if event.select.id in ("start-kind", "goal-kind"):
            self._apply_kind(str(event.select.id).removesuffix("-kind"))
        elif event.select.id == "method":
            self._apply_method()

    def _apply_kind(self, which: str) -> None:
        """Judge the start/goal fields as θ or as an orientation (the typed text back in
        them); for home / current pose they show, disabled, the θ a solve uses."""
        kind = self.query_one(f"#{which}-kind", Select).value
        angles = self.query_one(f"#{which}-values", AnglesInput)
        if kind == "rpy":
            angles.set_rules(rpy_rules(f"{which} "), ik_check(self.session, f"{which} "))
        else:
            angles.set_rules(theta_rules(self.session.profile, f"{which} "))
        if kind in ("theta", "rpy"):
            typed = self._typed.pop(which, None)
            if typed is not None:
                for field, text in zip(angles.fields, typed, strict=True):
                    field.value = text
        else:
            self._typed.setdefault(which, [f.value for f in angles.fields])
            self._show_pose(which)
        angles.set_enabled(kind in ("theta", "rpy"))

    def _show_pose(self, which: str) -> None:
        """The θ that "home" or "current pose" stands for now (the last reading of the
        servos; empty, "not read", before the first)."""
        kind = self.query_one(f"#{which}-kind", Select).value
        if kind not in ("home", "current"):
            return
        angles = self.query_one(f"#{which}-values", AnglesInput)
        pose = (self.session.profile.home.theta_deg if kind == "home"
                else self.session.theta_deg)
        if pose is None:
            for field in angles.fields:
                field.value = ""
                field.placeholder = "not read"
        else:
            angles.set_values(pose)

    def refresh_view(self) -> None:
        super().refresh_view()
        for which in ("start", "goal"):
            self._show_pose(which)

    def _apply_method(self) -> None:
        """N is the MVN horizon; minimum time finds its own (the field is then unused)."""
        self.query_one("#steps-row", NumberRow).set_enabled(
            self.query_one("#method", Select).value == "mvn")

    def on_input_submitted(self, event: Input.Submitted) -> None:
        event.stop()
        self.action_solve()

    def _spec(self, which: str) -> PoseSpec:
        kind = self.query_one(f"#{which}-kind", Select).value
        if kind in ("current", "home"):
            return PoseSpec(kind)
        v = self.query_one(f"#{which}-values", AnglesInput).values()
        return PoseSpec(kind, (v[0], v[1], v[2]))  # type: ignore[arg-type]

    def _params(self) -> tuple[str, int, float, int, bool]:
        method = str(self.query_one("#method", Select).value)
        steps = (int(self.query_one("#steps-row", NumberRow).number()) if method == "mvn"
                 else DEFAULT_STEPS)  # unused by minimum time
        vmax = self.query_one("#vmax-row", NumberRow).number()
        k = int(self.query_one("#intersample-row", NumberRow).number())
        hold_first = not self.query_one("#free-first", Checkbox).value
        return method, steps, vmax, k, hold_first

    def action_solve(self) -> None:
        try:
            start, goal = self._spec("start"), self._spec("goal")
            method, steps, vmax, k, hold_first = self._params()
        except BadInputError as exc:  # the field says why too; nothing is solved
            self._drop_plan(f"No plan: the solve was refused.\n{exc.message}\n"
                            "Next: fix the field marked invalid, then press s.")
            self.status.error(f"Solve refused (no plan now): {exc.message}. Fix the field, "
                              "then press s.")
            return
        name = METHOD_NAMES[method]
        self.solving_method = method
        s = self.session
        # "current pose" is where the servos are now: read it (when connected) just before
        # solving, so the plan starts from it and the start fields show it
        read = "current" in (start.kind, goal.kind) and s.bus is not None

        def solve() -> PlanSolved:
            if read:
                s.read_position()
            plan = s.plans.solve(method, start, goal, s.theta_deg,  # type: ignore[arg-type]
                                 steps, vmax, intersample=k, hold_first=hold_first,
                                 start_read=read and start.kind == "current")
            return PlanSolved(plan)

        self.run_blocking("solve", solve,
                          f"solving the {name} problem ({start.describe()} → "
                          f"{goal.describe()}) …")

    # --- saved plans and remembered values ------------------------------------------------
    def action_open(self) -> None:
        plans = sorted(Path("plans").glob("*.json")) if Path("plans").is_dir() else []
        body = ("A plan file is checked against this profile and verified exactly as the "
                "executor will before it becomes the current plan.")
        self.app.push_screen(
            AskPathScreen("Open a saved plan", body, str(plans[-1]) if plans else "plans/"),
            self._open_path)

    def _open_path(self, path: str | None) -> None:
        if not path:
            self.status.ok("open cancelled: the current plan is unchanged")
            return
        self.solving_method = "open"
        self.run_blocking("open", lambda: PlanLoaded(self.session.plans.open(path), path),
                          f"reading and verifying {path} …")

    def _fields(self) -> dict[str, Input]:
        out: dict[str, Input] = {f"{w}.{i}": f for w in ("start", "goal")
               for i, f in enumerate(self.query_one(f"#{w}-values", AnglesInput).fields)}
        for name in ("steps", "vmax", "intersample"):
            out[name] = self.query_one(f"#{name}", Input)
        return out

    def _remember(self) -> None:
        """What the operator typed, as typed, for this profile's next session (not the pose
        the start / goal fields show for home or current pose)."""
        mem, prof = self.console.form_memory, self.session.profile.name
        for key, field in self._fields().items():
            which, _, i = key.partition(".")
            typed = self._typed.get(which)
            mem.put(prof, f"plan.{key}", typed[int(i)] if typed is not None else field.value)
        for sel in ("start-kind", "goal-kind", "method"):
            mem.put(prof, f"plan.{sel}", str(self.query_one(f"#{sel}", Select).value))
        mem.put(prof, "plan.free-first", str(bool(self.query_one("#free-first", Checkbox).value)))
        if not mem.save():
            self.notify(f"form values not remembered: {mem.error}", severity="warning",
                        markup=False)

    def _recall(self) -> None:
        mem, prof = self.console.form_memory, self.session.profile.name
        for sel, options in (("start-kind", POSE_KINDS), ("goal-kind", POSE_KINDS),
                             ("method", METHODS)):
            value = mem.get(prof, f"plan.{sel}")
            if value is not None and value in {v for _, v in options}:
                self.query_one(f"#{sel}", Select).value = value
        for key, field in self._fields().items():
            text = mem.get(prof, f"plan.{key}")
            if text is not None:
                field.value = text
        if mem.get(prof, "plan.free-first") == "True":
            self.query_one("#free-first", Checkbox).value = True

    def action_next_plot(self) -> None:
        self.plot_kind = (self.plot_kind + 1) % len(PLOTS)
        self.show_plot()

    def action_save(self) -> None:
        plan = self.session.plans.plan
        if plan is None:
            self.status.error("no plan yet: press s to solve one")
            return

        def save() -> PlanSaved:
            import time


            path = Path("plans") / f"{time.strftime('%Y%m%d-%H%M%S')}-{plan.kind}.json"
            path.parent.mkdir(exist_ok=True)
            save_plan(plan, path)
            return PlanSaved(path)

        self.run_blocking("save", save, "saving the plan …")

    def handle_done(self, outcome: Outcome) -> None:
        if isinstance(outcome, PlanSolved):
            self.show_plan()
            plan = outcome.plan
            self.console.view.show_plan(plan.position_deg)
            where = " (path and goal ghost in the 3D view)" if self.console.viewer_url else ""
            self.status.ok(f"solved in {plan.solve_seconds:.2f} s: {plan.duration_s:.2f} s of "
                           f"motion. Press 5 to execute it{where}")
            self._remember()
        elif isinstance(outcome, PlanLoaded):
            self.show_plan()
            self.console.view.show_plan(outcome.plan.position_deg)
            self.status.ok(f"opened {outcome.path}: {outcome.plan.kind}, "
                           f"{outcome.plan.duration_s:.2f} s of motion, verified. Press 5 to "
                           "execute it")
        elif isinstance(outcome, PlanSaved):
            self.status.ok(f"plan saved to {outcome.path}")

    def on_failed(self, message: Failed) -> None:
        """The planner's words are the CLI's too: put the console's (fields, keys) in their
        place. Runs first; Textual then calls StepScreen.on_failed with the new words."""
        message.message = console_words(message.message)
        self._solver_failed = message.solver_failed
        self._issue = message.issue

    def handle_failed(self, op: str, message: str) -> None:
        if op == "open":  # the current plan stays: nothing replaced it
            self.status.error(f"plan not opened (the current plan is unchanged): {message}")
            return
        if op != "solve":
            return  # a failed save replaces nothing: the status line says why
        name = METHOD_NAMES.get(self.solving_method, self.solving_method)
        # a solver that failed, or a request answered with its reason (an end not feasible,
        # no plan within the bounds): only the first is "the solve failed"
        if self._solver_failed:
            head, line = f"No plan: the {name} solve failed.", f"{name} solve failed (no plan now)"
        else:
            head, line = f"No {name} plan:", f"no {name} plan"
        self._drop_plan(f"{head}\n{message}\nNext: {next_step(self._issue)}")
        self.status.error(f"{line}: {message}")

    def _drop_plan(self, text: str) -> None:
        """The plan a refused or failed solve would have replaced is gone from the screen,
        the 3D view and the session: "execute" never runs a plan the operator tried to
        replace."""
        self.session.plans.clear()
        self.console.view.clear_path()
        self.query_one("#plan-text", Static).update(Content(text))
        self.query_one("#plan-plot", PlotView).plot("no plan", np.zeros(0), [])
        self.refresh_view()  # the step bar's tick and "Next:" line no longer name a plan

    def show_plan(self) -> None:
        plan, info = self.session.plans.plan, self.session.plans.info
        if plan is None or info is None:  # the session sets both together
            return
        self.query_one("#plan-text", Static).update(Content(plan_text(plan, info)))
        self.show_plot()

    def show_plot(self) -> None:
        plan = self.session.plans.plan
        view = self.query_one("#plan-plot", PlotView)
        if plan is None:
            return
        t = np.arange(plan.N + 1) * plan.Ts
        if PLOTS[self.plot_kind] == "positions":
            series = joint_series("θ*", plan.reference_deg, faint=True)
            series += joint_series("θ", plan.position_deg)
            view.plot("references θ* (dots), model positions θ [deg]", t, series)
        else:
            view.plot("model velocities dθ/dt [deg/s]", t,
                      joint_series("dθ/dt ", plan.velocity_degps))
