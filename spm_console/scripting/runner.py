"""Headless scripted sessions: ``spm-console script FILE.toml``.

A script is a TOML file with an optional ``[session]`` table and a list of
``[[step]]`` tables run in order on one :class:`~spm_console.services.session.Session`
— the same core, bus, executor and safety checks as the console. Angles in
degrees, time in seconds. Format (see ``examples/session.toml``)::

    [session]
    profile = "profiles/agile_wrist.toml"  # relative to the working directory
    port = ""                 # serial device; "" or absent = the emulated bus
    initial_deg = [130, 140, 133]          # emulated bus only: power-on θ
    faults = ["stall:2@5.0"]  # emulated bus only: faults (seconds after connect)
    logs = "logs"             # run log folder

    [[step]]
    do = "home"               # read θ, check the assembly mode, move home (logged)

    [[step]]
    do = "fk"                 # unique FK of θ, or of an orientation (IK first)
    theta = [95, 110, 105]    # or: rpy = [10, 5, -15]
    all_modes = false

    [[step]]
    do = "workspace"          # load the cached workspace (build it if missing)
    rebuild = false
    check = [95, 110, 105]    # optional: also check this θ

    [[step]]
    do = "plan"
    method = "mvn"            # or "mintime"
    start = "current"         # "current" | "home" | {theta = [...]} | {rpy = [...]}
    goal = {theta = [95, 110, 105]}
    steps = 150               # MVN horizon N
    vmax = 50                 # deg/s (default: the profile's limits.vmax_degps)

    [[step]]
    do = "execute"            # the last plan (approach move first if needed)
    allow_stop = false        # true: a safety stop is a result, not the end of the script

    [[step]]
    do = "wait"
    seconds = 0.5

    [[step]]
    do = "assert"             # every given condition must hold, else exit code 11
    outcome = "completed"     # of the last home/execute
    exit_code = 0             # of the last home/execute
    theta_near = [95, 110, 105]            # measured θ now, within tol_deg
    tol_deg = 0.5
    feasible = true           # of the last fk
    zeta_min = 0.3            # the last fk's ζ is at least this
    max_duration_s = 4.0      # the last plan lasts at most this

Progress goes to stderr, one line per step; the summary is one JSON object on
stdout: ``{"ok", "exit_code", "message", "steps": [{"index", "do", "ok", "seconds",
"result" | "error"}], ...}``. The first failing step ends the script with its
error's exit code (a safety stop with its stop code; a failed assertion with 11);
the wrist is left as the executor's stop action leaves it.
"""

from __future__ import annotations

import signal
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from spm_console.config.load import load_profile
from spm_console.config.schema import DEFAULT_PROFILE, Profile
from spm_console.devices.emulator.faults import parse_fault
from spm_console.errors import BadInputError, ExitCode, RefusedError, SpmError
from spm_console.refusals import worded
from spm_console.scripting.checks import check_plan_ends, check_script, plan_ends
from spm_console.scripting.steps import (
    AssertStep,
    ExecuteStep,
    FkStep,
    FollowStep,
    HomeStep,
    PlanStep,
    PoseIn,
    RpyPose,
    Script,
    ScriptAssertionError,
    ThetaPose,
    WaitStep,
    WorkspaceStep,
)
from spm_console.services.kin_record import FkRecord
from spm_console.services.session import Session
from spm_console.services.wrist_service import PoseSpec
from spm_console.store.target_file import read_target_csv, timed_targets
from spm_console.system.signals import SignalInterrupt, stop_signals


def _pose(p: PoseIn) -> PoseSpec:
    if isinstance(p, ThetaPose):
        return PoseSpec("theta", p.theta)
    if isinstance(p, RpyPose):
        return PoseSpec("rpy", p.rpy)
    return PoseSpec(p)


def _vec(v: Any) -> list[float]:
    return [round(float(x), 6) for x in np.ravel(v)]


@dataclass
class StepReport:
    index: int
    do: str
    ok: bool
    seconds: float
    result: dict[str, Any] = field(default_factory=dict)
    error: str = ""

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"index": self.index, "do": self.do, "ok": self.ok,
                             "seconds": round(self.seconds, 4)}
        if self.ok or self.result:
            d["result"] = self.result
        if self.error:
            d["error"] = self.error
        return d


class ScriptRunner:
    """Runs a :class:`Script` on a :class:`Session`; :meth:`run` returns the exit code."""

    def __init__(self, script: Script, session: Session,
                 progress: Callable[[str], None] | None = None) -> None:
        self.script = script
        self.session = session
        self.progress = progress or (lambda line: None)
        self.reports: list[StepReport] = []
        self.last_fk: FkRecord | None = None
        self.exit_code = ExitCode.OK
        self.message = ""
        self._interrupted = False
        self._in_step = False

    def interrupt(self, sig: signal.Signals = signal.SIGTERM) -> None:
        """A terminating signal: E-stop any motion and skip the remaining steps.

        Called from the signal handler. A motion is stopped by its executor (the
        execute or home step then fails with the stop's code, 20); when nothing moves,
        the step under way is abandoned like on Ctrl-C (exit 130).
        """
        self._interrupted = True
        if not self.session.estop(f"signal {sig.name}", by_signal=True) and self._in_step:
            raise SignalInterrupt(sig.name)

    def run(self) -> int:
        steps = self.script.step
        n = len(steps)
        for i, step in enumerate(steps, start=1):
            if self._interrupted:
                self.exit_code, self.message = ExitCode.INTERRUPTED, "interrupted"
                break
            t0 = time.perf_counter()
            try:
                self._in_step = True
                try:
                    result, summary = self._do(step)
                finally:
                    self._in_step = False
            except SpmError as exc:
                if isinstance(exc, RefusedError):  # the motion process's refusal, in our words
                    exc.message = worded(exc.reason, "script")
                self.reports.append(StepReport(i, step.do, False, time.perf_counter() - t0,
                                               getattr(exc, "result", {}), exc.message))
                self.progress(f"[{i}/{n}] {step.do}: FAILED: {exc.message}")
                self.exit_code, self.message = exc.exit_code, f"step {i} ({step.do}): {exc.message}"
                break
            except KeyboardInterrupt:
                self.session.estop("interrupted")
                self.reports.append(StepReport(i, step.do, False, time.perf_counter() - t0,
                                               error="interrupted"))
                self.exit_code, self.message = ExitCode.INTERRUPTED, f"step {i} ({step.do}) interrupted"
                break
            self.reports.append(StepReport(i, step.do, True, time.perf_counter() - t0, result))
            self.progress(f"[{i}/{n}] {step.do}: {summary}")
        else:
            self.message = f"{n} steps done"
        return int(self.exit_code)

    def summary(self) -> dict[str, Any]:
        s = self.session
        return {
            "ok": self.exit_code == ExitCode.OK, "exit_code": int(self.exit_code),
            "message": self.message, "profile": s.profile.name, "bus": s.bus_label,
            "steps": [r.to_dict() for r in self.reports],
        }

    # ------------------------------------------------------------------ steps
    def _do(self, step: Any) -> tuple[dict[str, Any], str]:
        handler: Callable[[Any], tuple[dict[str, Any], str]] = getattr(self, f"_step_{step.do}")
        return handler(step)

    def _ensure_bus(self) -> None:
        if self.session.bus is None:
            st = self.session.connect()
            self.progress(f"      connected: {len(st.statuses)} servos on the {self.session.bus_label}")

    def _motion(self, res: Any, allow_stop: bool, what: str) -> tuple[dict[str, Any], str]:
        rec = {"outcome": res.outcome, "exit_code": int(res.exit_code), "message": res.message,
               "log_dir": str(res.log_dir) if res.log_dir else None,
               "final_deg": None if res.final_deg is None else _vec(res.final_deg)}
        if not res.ok and not allow_stop:
            err = SpmError(f"{what} stopped: {res.message} (log {res.log_dir})")
            err.exit_code = res.exit_code
            err.result = rec  # type: ignore[attr-defined]
            raise err
        return rec, f"{res.outcome}: {res.message}; log {res.log_dir}"

    def _step_home(self, step: HomeStep) -> tuple[dict[str, Any], str]:
        self._ensure_bus()
        return self._motion(self.session.home(), False, "homing")

    def _step_fk(self, step: FkStep) -> tuple[dict[str, Any], str]:
        if (step.theta is None) == (step.rpy is None):
            raise BadInputError("fk step: give exactly one of theta or rpy")
        wrist = self.session.wrist
        theta = step.theta if step.theta is not None else wrist.ik(step.rpy)  # type: ignore[arg-type]
        rec = wrist.fk(theta, all_modes=step.all_modes)
        self.last_fk = rec
        out = {"theta_deg": _vec(rec.theta_deg), "v": [_vec(r) for r in rec.v],
               "n": _vec(rec.n), "zeta": float(rec.zeta), "residual": float(rec.residual),
               "min_link_distance_mm": float(rec.min_link_distance_mm),
               "feasible": bool(rec.feasible), "reason": rec.reason}
        if rec.modes is not None:
            out["modes"] = len(rec.modes)
        verdict = "feasible" if rec.feasible else f"NOT feasible ({rec.reason})"
        return out, f"θ = {out['theta_deg']}° -> n = {out['n']}, ζ = {out['zeta']:.3f}, {verdict}"

    def _step_workspace(self, step: WorkspaceStep) -> tuple[dict[str, Any], str]:
        ws = self.session.wrist.load_workspace(force=step.rebuild)
        info = self.session.wrist.cache_info
        assert info is not None  # set with the workspace
        out: dict[str, Any] = {**ws.counts(), "halfspaces": ws.region.halfspaces,
                               "cache": str(info.path), "cache_hit": bool(info.hit),
                               "seconds": info.load_seconds + info.build_seconds}
        text = (f"{out['feasible']} of {out['nodes']} nodes feasible, P has "
                f"{out['halfspaces']} half-spaces ({'cached' if info.hit else 'built'})")
        if step.check is not None:
            chk = self.session.wrist.check_theta(step.check)
            out["check"] = {"theta_deg": _vec(chk.theta_deg), "feasible": bool(chk.feasible),
                            "in_region": bool(chk.in_region), "plannable": bool(chk.plannable),
                            "verdict": chk.verdict, "reason": chk.reason}
            text += f"; θ = {list(step.check)}°: {chk.verdict}"
        return out, text

    def _step_plan(self, step: PlanStep) -> tuple[dict[str, Any], str]:
        if self.session.wrist.workspace is None:
            self.session.wrist.load_workspace()
        if "current" in (step.start, step.goal):
            self._ensure_bus()
            self.session.read_position()
        s = self.session.plans.solve(step.method, _pose(step.start), _pose(step.goal),
                                     self.session.theta_deg, step.steps, step.vmax).summary()
        out = {**s.figures(), "start_deg": _vec(s.start_deg), "goal_deg": _vec(s.goal_deg),
               "max_speed_degps": s.max_speed_degps}
        return out, f"{s.kind} N = {s.N} ({s.duration_s:.2f} s), solved in {s.solve_seconds:.2f} s"

    def _step_execute(self, step: ExecuteStep) -> tuple[dict[str, Any], str]:
        self._ensure_bus()
        plans = self.session.plans
        return self._motion(self.session.execute(plans.require(), source=plans.source),
                            step.allow_stop, "execution")

    def _step_follow(self, step: FollowStep) -> tuple[dict[str, Any], str]:
        if (step.targets is None) == (step.file is None):
            raise BadInputError("follow step: give exactly one of targets or file")
        if step.file is not None:
            timed = read_target_csv(self.session.profile, Path(step.file), step.rpy)  # cwd-relative
        else:  # as the script's check took them (scripting.checks)
            timed = timed_targets(self.session.profile, [
                (f"key 'targets' row {k}", r) for k, r in enumerate(step.targets or (), 1)], step.rpy)
        self._ensure_bus()
        out = self.session.following.follow(timed, source="script")
        rec, text = self._motion(out.execution, step.allow_stop, "following")
        if out.stats is not None:
            rec["follow"] = out.stats.to_dict()
            text += (f"; {out.stats.solves} re-plans, solve p99 {out.stats.solve_ms_p99:.2f} ms, "
                     f"{out.stats.misses} missed")
        return rec, text

    def _step_wait(self, step: WaitStep) -> tuple[dict[str, Any], str]:
        t_end = time.monotonic() + step.seconds
        while not self._interrupted and (rem := t_end - time.monotonic()) > 0:
            time.sleep(min(rem, 0.05))
        return {"seconds": step.seconds}, f"waited {step.seconds:g} s"

    def _step_assert(self, step: AssertStep) -> tuple[dict[str, Any], str]:
        s = self.session
        run = s.last_run
        checks: list[tuple[str, bool, str]] = []
        if step.outcome is not None or step.exit_code is not None:
            if run is None:
                raise ScriptAssertionError("assert: no home or execute step has run yet")
            if step.outcome is not None:
                checks.append(("outcome", run.outcome == step.outcome,
                               f"outcome is {run.outcome!r}, expected {step.outcome!r}"))
            if step.exit_code is not None:
                checks.append(("exit_code", int(run.exit_code) == step.exit_code,
                               f"exit code is {int(run.exit_code)}, expected {step.exit_code}"))
        if step.theta_near is not None:
            now = s.read_position() if s.bus is not None else None
            if now is None:
                raise ScriptAssertionError("assert theta_near: not connected to the servos")
            dist = float(np.abs(now - np.asarray(step.theta_near)).max())
            checks.append(("theta_near", dist <= step.tol_deg,
                           f"θ = {_vec(now)}° is {dist:.3f}° from {list(step.theta_near)}° "
                           f"(tolerance {step.tol_deg}°)"))
        if step.feasible is not None or step.zeta_min is not None:
            fk = self.last_fk
            if fk is None:
                raise ScriptAssertionError("assert: no fk step has run yet")
            if step.feasible is not None:
                checks.append(("feasible", bool(fk.feasible) == step.feasible,
                               f"feasible is {bool(fk.feasible)}" +
                               (f" ({fk.reason})" if fk.reason else "")))
            if step.zeta_min is not None:
                checks.append(("zeta_min", float(fk.zeta) >= step.zeta_min,
                               f"ζ = {float(fk.zeta):.4f}, expected ≥ {step.zeta_min}"))
        if step.max_duration_s is not None:
            if s.plans.plan is None:
                raise ScriptAssertionError("assert max_duration_s: no plan step has run yet")
            lasts = s.plans.plan.duration_s
            checks.append(("max_duration_s", lasts <= step.max_duration_s + 1e-9,
                           f"plan lasts {lasts:.3f} s, expected ≤ {step.max_duration_s} s"))
        if not checks:
            raise BadInputError("assert step: no condition given")
        failed = [msg for _, ok, msg in checks if not ok]
        result = {name: ok for name, ok, _ in checks}
        if failed:
            err = ScriptAssertionError("assertion failed: " + "; ".join(failed))
            err.result = result  # type: ignore[attr-defined]
            raise err
        return result, "all hold: " + ", ".join(name for name, _, _ in checks)


def session_for(script: Script, profile: Profile | None = None, port: str | None = None,
                sim: bool = False, logs: Path | None = None) -> Session:
    """The session a script runs on: command-line choices win over the ``[session]`` table."""

    spec = script.session
    if profile is None:
        profile = load_profile(spec.profile or DEFAULT_PROFILE)
    check_script(script, profile)  # the CLI's input rules, before the bus is opened
    dev = None if sim else (port or spec.port or profile.bus.port or None)
    faults = [parse_fault(f) for f in spec.faults]
    if dev is not None and (faults or spec.initial_deg is not None or spec.plant is not None):
        raise BadInputError("[session] faults, initial_deg and plant apply to the emulated bus "
                            "only")
    if spec.plant is not None:
        profile = profile.model_copy(update={"plant": profile.plant.model_copy(
            update={"model": spec.plant})})
    logs_dir = logs if logs is not None else (Path(spec.logs) if spec.logs else None)
    session = Session(profile, port=dev, sim=dev is None, logs_root=logs_dir, faults=faults,
                      initial_deg=spec.initial_deg)
    if plan_ends(script, profile):  # a plan's given end not feasible: refused before homing
        try:
            check_plan_ends(script, profile, session.wrist.load_workspace())
        except BaseException:
            session.close()
            raise
    return session


def run_script(script: Script, session: Session, progress: Callable[[str], None]) -> ScriptRunner:
    """Run with every terminating signal (:mod:`spm_console.system.signals`) turned into an
    E-stop and a clean end; the session is closed after."""
    runner = ScriptRunner(script, session, progress)
    with stop_signals(runner.interrupt):  # (while closing, a signal has nothing left to stop)
        try:
            runner.run()
        finally:
            session.close()
    return runner
