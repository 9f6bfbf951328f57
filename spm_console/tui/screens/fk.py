"""Step 2: FK check — θ (or an orientation) in, the unique pose and its quality out."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from textual.app import ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Vertical
from textual.content import Content
from textual.widgets import Input, Static

from spm_console.errors import BadInputError
from spm_console.formatting import fmt_deg, fmt_residual, fmt_vec
from spm_console.services.kin_record import FkRecord
from spm_console.tui.messages import FkSolved, Outcome
from spm_console.tui.screens.base import StepScreen
from spm_console.tui.widgets.angles import AnglesInput
from spm_console.tui.widgets.rules import RPY_NAMES, THETA_NAMES, ik_check, rpy_rules, theta_rules


def fk_text(rec: FkRecord) -> str:
    """The FK record as aligned lines (the numbers of ``spm-console fk``)."""
    lines = [f"θ        = {fmt_deg(rec.theta_deg)}"]
    lines += [f"v{i + 1}       = {fmt_vec(rec.v[i], signed=True)}" for i in range(3)]
    lines += [
        f"n        = {fmt_vec(rec.n, signed=True)}",
        f"ζ        = {rec.zeta:.4f}",
        f"residual {fmt_residual(rec.residual)}",
        f"closest links = {rec.min_link_distance_mm:.1f} mm ({rec.closest_pair})",
        "FEASIBLE" if rec.feasible else f"NOT FEASIBLE: {rec.reason}",
    ]
    if rec.path is not None and rec.path.route == "graph":  # around a singularity: say which way
        lines.append(rec.path.line())
    if rec.modes is not None:
        lines.append(f"{len(rec.modes)} assembly modes at this θ:")
        for k, m in enumerate(rec.modes, 1):
            tag = "  ← home-connected (the unique solution)" if m.home_connected else ""
            lines.append(f"  {k}: n = {fmt_vec(m.n, 3, signed=True)}  ζ = {m.zeta:.3f}{tag}")
    return "\n".join(lines)


class FkScreen(StepScreen):
    MODE = "fk"
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("f", "fk", "FK"),
        Binding("i", "ik", "IK"),
        Binding("m", "modes", "Modes"),
        Binding("c", "current", "Current"),
        Binding("tab", "move_focus('next')", "Fields", priority=True),
        Binding("escape", "leave_field", "Leave", priority=True),
    ]

    def compose_body(self) -> ComposeResult:
        prof = self.session.profile
        with Vertical(classes="body"):
            yield AnglesInput("Motor angles θ (deg)", THETA_NAMES, prof.home.theta_deg,
                              rules=theta_rules(prof), id="theta")
            yield AnglesInput("Orientation from home (deg)", RPY_NAMES, (0.0, 0.0, 0.0),
                              rules=rpy_rules(), check=ik_check(self.session), id="rpy")
            yield Static(id="fk-result", markup=False, classes="result")

    def on_mount(self) -> None:
        if self.session.theta_deg is not None:
            self.query_one("#theta", AnglesInput).set_values(self.session.theta_deg)
        self.query_one("#fk-result", Static).update(Content(
            "Enter θ and press f (or Enter), or an orientation and press i."))

    def on_input_submitted(self, event: Input.Submitted) -> None:
        event.stop()
        parent = event.input.parent
        if isinstance(parent, AnglesInput) and parent.id == "rpy":
            self.action_ik()
        else:
            self.action_fk()

    def _values(self, which: str, action: str, key: str) -> list[float] | None:
        """The fields' numbers, or None after saying why ``action`` is refused."""
        angles = self.query_one(f"#{which}", AnglesInput)
        try:
            return angles.values()
        except BadInputError as exc:  # the field says why too; nothing is computed
            self.status.error(f"{action} refused: {exc.message}. Fix the field, then "
                              f"press {key}.")
            # the result shown was for other numbers: cleared, with the reason in its place
            self.query_one("#fk-result", Static).update(Content(
                f"No result: {action} refused.\n{exc.message}\nNext: fix the field, then "
                f"press {key}."))
            self.console.view.show_target(None)
            return None

    def action_fk(self, all_modes: bool = False) -> None:
        theta = self._values("theta", "FK", "m" if all_modes else "f")
        if theta is None:
            return
        what = "all assembly modes" if all_modes else "FK"
        s = self.session

        def go() -> FkSolved:
            from spm_console.tui.screens.jog import rpy_of

            return FkSolved(s.wrist.fk(theta, all_modes=all_modes), rpy_deg=rpy_of(s, np.asarray(theta)))

        self.run_blocking("fk", go, f"solving {what} of θ = {fmt_deg(theta)} …")

    def action_modes(self) -> None:
        self.action_fk(all_modes=True)

    def action_ik(self) -> None:
        rpy = self._values("rpy", "IK", "i")
        if rpy is None:
            return

        def go() -> FkSolved:
            theta = self.session.wrist.ik(rpy)
            return FkSolved(self.session.wrist.fk(theta), from_ik=True, rpy_deg=np.asarray(rpy, float))

        self.run_blocking("ik", go, f"solving IK of roll/pitch/yaw = {fmt_deg(rpy)} …")

    def action_current(self) -> None:
        if self.session.theta_deg is None:
            self.status.error("current θ unknown: connect first (press 1, then c)")
            return
        self.query_one("#theta", AnglesInput).set_values(self.session.theta_deg)
        self.action_fk()

    def handle_done(self, outcome: Outcome) -> None:
        if not isinstance(outcome, FkSolved):
            return
        rec = outcome.record
        if outcome.from_ik:
            self.query_one("#theta", AnglesInput).set_values(rec.theta_deg, digits=3)
        elif outcome.rpy_deg is not None:  # the orientation fields show this pose's, not older ones
            self.query_one("#rpy", AnglesInput).set_values(outcome.rpy_deg)
        self.query_one("#fk-result", Static).update(Content(fk_text(rec)))
        self.console.fk_done = True
        self.console.view.show_target(np.asarray(rec.theta_deg, float))
        verdict = "feasible" if rec.feasible else "not feasible"
        where = " (shown as the target ghost in the 3D view)" if self.console.viewer_url else ""
        what = "IK and FK solved" if outcome.from_ik else "FK solved"
        self.status.ok(f"{what}: ζ = {rec.zeta:.3f}, {verdict}{where}")

    def handle_failed(self, op: str, message: str) -> None:
        # the result this would have replaced is cleared; the 3D view goes back to the wrist
        what = "IK" if op == "ik" else "FK"
        nxt = ("change roll/pitch/yaw, then press i" if op == "ik" else
               "change θ, then press f (or c for the current pose)")
        self.query_one("#fk-result", Static).update(Content(
            f"No result: {what} failed.\n{message}\nNext: {nxt}."))
        self.status.error(f"{what} failed: {message}")
        self.console.view.show_target(None)
