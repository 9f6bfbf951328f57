"""Step 1's identification experiment (key i), the base of the connect screen: asked first,
run like any motion, then the whole result shown (on the step, wrapped, and in the question
that follows) and "Use the identified servo model now?". Yes restarts the console on the
identified profile (as the settings do: :class:`~spm_console.tui.switch.SwitchRequest`) with
the workspace kept — the geometry did not change — and without the plan, which the old model
planned."""

from __future__ import annotations

from textual.content import Content
from textual.widgets import Static

from spm_console.refusals import Refusal, worded
from spm_console.tui.messages import IdentifyDone
from spm_console.tui.screens.base import StepScreen
from spm_console.tui.switch import SwitchRequest
from spm_console.tui.widgets.confirm import ConfirmScreen, LongConfirm

USE_TITLE = "Use the identified servo model now?"


class IdentifyStep(StepScreen):
    """The connect screen's identification (its result panel is ``#identify-result``)."""

    def __init__(self) -> None:
        super().__init__()
        self._motion_label = "homing"
        """What the running motion is, as the telemetry line names it."""

    def _ready(self, what: str) -> bool:
        """Connected and idle, or say why not."""
        if self.session.bus is None:
            self.status.error(f"{what}: not connected, press c to connect first")
            return False
        if self.busy_op or self.console.moving:
            self.status.error(f"{what}: busy, wait for the current operation")
            return False
        return True

    def action_identify(self) -> None:
        if not self._ready("identify"):
            return
        if not self.session.homed:
            self.status.error(f"identify refused: {worded(Refusal.NOT_HOMED, 'console')}")
            return
        # scipy's optimizers and matplotlib: loaded when asked for, not before the first screen
        from spm_console.tui.identify_run import question

        self.app.push_screen(ConfirmScreen("Identify the servos?", question(self.session)),
                             self._identify_confirmed)

    def _identify_confirmed(self, yes: bool | None) -> None:
        if not yes:
            self.status.ok("identification cancelled: nothing moved")
            return
        from spm_console.tui.identify_run import identify_blocking

        on_sample = self.console.telemetry_sink(self)
        self.console.moving = True
        self._motion_label = "identification experiment"
        path = self.console.profile_path
        if not self.run_blocking("identify", lambda: identify_blocking(
                self.session, path, on_sample), "identification experiment …"):
            self.console.moving = False

    def identify_done(self, done: IdentifyDone) -> None:
        """The experiment ended: its outcome; when it completed, the whole result on the step
        and the question whether to use it."""
        self.console.moving = False
        self.console.after_motion(done.result)
        if not done.result.ok:
            self.status.run_result(f"identification stopped: {done.result.message}. "
                                   f"Log: {done.result.log_dir}", done.result)
            return
        self.status.run_result(done.summary, done.result)
        panel = self.query_one("#identify-result", Static)
        panel.update(Content("\n".join(done.lines)))
        panel.display = True
        if done.profile is not None:
            self.app.push_screen(LongConfirm(USE_TITLE, self._use_question(done)),
                                 lambda yes: self._use_answered(yes, done))

    def _use_question(self, done: IdentifyDone) -> str:
        step = float(self.session.profile.workspace.step_deg)
        return "\n".join([
            done.lines[0],
            f"Yes: the console restarts on this profile at grid step {step:g}° (as the "
            "settings do): the servos are disconnected (home again), the workspace is kept "
            "(the geometry did not change), the plan is dropped (the old model planned it).",
            "No: the profile in use stays; the settings (ctrl+o) list the identified one.",
            "", *done.lines[1:]])

    def _use_answered(self, yes: bool | None, done: IdentifyDone) -> None:
        s = self.session
        if not yes or done.profile is None:
            self.status.ok(f"the profile in use stays {s.profile.name}; the identified one "
                           "is listed in the settings (ctrl+o)")
            return
        why = (f"Identified servo model in use: {done.profile} (the console restarted on it; "
               "the workspace was kept, the plan dropped). Home the wrist again (h).")
        request = SwitchRequest.keeping(done.profile, s.profile, s.wrist.workspace, s.wrist.cache_info, why)
        if not self.console.restart_with(request):
            self.status.error("the console did not restart: the wrist is moving")
