"""The real-time execution loop: references out, positions in, every Ts.

Cycle k starts at the absolute deadline t0 + k·Ts (no cumulative drift; a late
cycle does not shift the next ones). In each cycle:

1. sync-write θ*(k);
2. sync-read θ(k) (one immediate retry on a failed read; a cycle whose reads all
   fail counts as a communication failure);
3. Kalman update with the references as input and θ(k) as measurement
   (:class:`~spm_console.core.servo.estimation.KalmanVelocity`), propagated over the
   actual write and read instants (θ*(k−1) until θ*(k) is written, θ*(k) until the
   read), so a late cycle or a retried read does not bias the estimate;
4. the model's open-loop prediction: on the ideal grid (the plan's 'simulated'
   curve, logged) and at the actual instants (what the tracking check compares);
5. safety checks (:mod:`spm_console.motion.safety`), telemetry to ``on_sample`` and
   the run log.

Any stop — E-stop request, tracking error, n consecutive communication failures,
servo hardware error, position outside the region + margin or outside the servo
limits — applies the profile's ``safety.stop_action`` at once (hold: the measured
position becomes the goal, written again at the next deadline; torque_off) and
ends the run with that stop's exit code. Degrees and seconds throughout.

The bus transactions (set-up, steps 1–2, the hardware poll, release) and the stops are the
executor's bases' (:mod:`spm_console.motion.cycle`).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import servo_model_of, servo_tick_deg
from spm_console.config.schema import Profile
from spm_console.core.servo.estimation import FiniteDifference, KalmanVelocity, ModelPredictor
from spm_console.core.workspace.data import Workspace
from spm_console.devices.base import ServoBus
from spm_console.errors import BadInputError, ExitCode, PlanRefusedError, SpmError
from spm_console.formatting import fmt_deg
from spm_console.motion.cycle.state import LoopState
from spm_console.motion.cycle.stops import StoppableLoop
from spm_console.motion.goals.load_offsets import load_offsets, sent_references
from spm_console.motion.goals.settle import Settling, settle_periods
from spm_console.motion.logs.runlog import RunLog
from spm_console.motion.plan_check import LINE_PHASES, PlanCheck, PlanVerifier
from spm_console.motion.safety import SafetyMonitor, StopReason
from spm_console.motion.sample import Sample
from spm_console.motion.segments import ExecutionResult, Segment
from spm_console.motion.stats import (
    SettleOutcome,
    StopTiming,
    model_health,
    run_stats,
    stale_replies,
)
from spm_console.system.cpus import placement
from spm_console.system.realtime import (
    LOOP_PRIORITY,
    RtGrant,
    kernel_preemption,
    release_realtime,
    request_realtime,
)

F = NDArray[np.float64]
#: A cycle still busy after this fraction of the period is logged (``slow_cycle``: late start,
#: bus, filter, hardware poll and checks, in ms).
SLOW_CYCLE = 0.75


class Executor(StoppableLoop):
    """Streams plans to a :class:`ServoBus` under the profile's safety rules.

    ``on_sample`` is called from the loop thread after every cycle (keep it quick);
    :meth:`request_estop` may be called from any thread.
    """

    def __init__(
        self,
        profile: Profile,
        bus: ServoBus,
        *,
        workspace: Workspace,
        log: RunLog | None = None,
        on_sample: Callable[[Sample], None] | None = None,
        on_start: Callable[[], None] | None = None,
        on_planned: Callable[[Sequence[Segment]], None] | None = None,
        read_retries: int = 1,
        hw_poll_every: int = 25,
        start_tolerance_deg: float | None = None,
        spin_s: float = 0.0015,
        clock: Callable[[], float] = time.perf_counter,
        sleep: Callable[[float], None] | None = None,
        emulated: bool = False,
        simulated_time: bool = False,
    ) -> None:
        KalmanVelocity.load()  # not after torque-on (see KalmanVelocity.load)
        super().__init__(profile, bus, log=log, read_retries=read_retries, spin_s=spin_s,
                         clock=clock, sleep=sleep)
        self.emulated = emulated
        """Driving the emulated bus (said in a communication-loss stop's reason)."""
        self.simulated_time = simulated_time
        """The emulated bus runs in simulated time (its replies cannot be late)."""
        self.verifier = PlanVerifier(profile, workspace)
        """Checks every plan against this profile's workspace before torque-on."""
        self.on_sample = on_sample
        self.on_start = on_start
        self.on_planned = on_planned
        """Told the segments once they are verified and the wrist is at their start, before
        anything moves (the motion process sends their duration to its front end)."""
        self.hw_poll_every = max(1, hw_poll_every)
        self.start_tolerance_deg = (profile.safety.approach_tolerance_deg
                                    if start_tolerance_deg is None else start_tolerance_deg)
        """How far the wrist may be from the first segment's start (default: the profile's
        approach tolerance, the rule every front end uses to add an approach move), deg."""
        self.ts = profile.servo.ts_s
        self.model = servo_model_of(profile)
        self.samples: list[Sample] = []
        self._last_good = np.zeros(3)
        self.realtime = RtGrant("normal", "not running")
        """The scheduling the loop thread got (logged as the "realtime" event)."""
        self.settle_outcome: SettleOutcome | None = None

    # ------------------------------------------------------------------ checks
    def check_plan(self, segments: Sequence[Segment]) -> PlanCheck:
        """The runtime's own verification (:mod:`spm_console.motion.plan_check`): refuses
        with :class:`PlanRefusedError` (exit 26) before anything moves; logged."""
        try:
            check = self.verifier.verify(segments)
        except PlanRefusedError as exc:
            self._event("plan_refused", message=exc.message)
            raise PlanRefusedError(f"{exc.message}; nothing moved") from None
        self._event("plan_verified", points=check.points, segments=check.segments,
                    max_speed_degps=check.max_speed_degps,
                    max_reference_step_deg=check.max_reference_step_deg,
                    ms=round(check.seconds * 1e3, 3))
        return check

    # ------------------------------------------------------------------ the loop
    def run(self, segments: Sequence[Segment], theta0_deg: F | None = None) -> ExecutionResult:
        """Execute the segments back to back; returns when done or stopped."""
        self.t0 = self.clock()  # set-up events: time since run() began (the loop resets t0)
        self._stale0 = stale_replies(self.bus)
        self.check_plan(segments)
        theta0 = self.read_initial() if theta0_deg is None else np.asarray(theta0_deg, float)
        start = segments[0].plan.reference_deg[0]
        gap = float(np.abs(theta0 - start).max())
        if gap > self.start_tolerance_deg:
            raise BadInputError(
                f"the wrist is at θ = {fmt_deg(theta0)} but the plan starts at "
                f"{fmt_deg(start)} ({gap:.2f}° away, tolerance "
                f"{self.start_tolerance_deg}°); move there first (execute adds an approach move)"
            )
        if self.on_planned is not None:
            self.on_planned(segments)
        # verified within 1e-9° of the servo limits: on them exactly (the bus refuses any goal past)
        refs = np.clip(np.vstack([s.plan.reference_deg for s in segments]), self.lo, self.hi)
        offsets = load_offsets(self.profile, self.model, refs, theta0)
        sent = sent_references(refs, offsets, self.lo, self.hi, theta0)
        if offsets is not None:
            self._event("load_offsets", max_deg=np.abs(offsets).max(axis=0),
                        mean_deg=offsets.mean(axis=0))
        phases = [s.phase for s in segments for _ in range(s.plan.N + 1)]
        # planned segments stay in the certified set; runtime-built straight moves were
        # checked exactly along their path instead (plan_check.LINE_PHASES)
        regions = [s.phase not in LINE_PHASES for s in segments for _ in range(s.plan.N + 1)]
        self._event("start", theta0_deg=theta0, cycles=len(refs),
                    segments=[(s.phase, s.plan.kind, s.plan.N) for s in segments])
        # a planned motion may end by settling at its goal (profile [settle]); a line does not
        settle = (self.profile.settle.duration_s > 0 and segments[-1].phase not in LINE_PHASES)
        return self._guarded(
            theta0, lambda: self._loop(refs, phases, regions, theta0, settle, sent),
            lambda: f"executed {len(self.samples)} cycles ({len(self.samples) * self.ts:.2f} s)")

    def _guarded(self, theta0: F, loop: Callable[[], StopReason | None],
                 done: Callable[[], str]) -> ExecutionResult:
        """Real-time priority, preflight (hardware, watchdog, torque on), ``loop``; whatever
        happens the wrist is left holding (or as the stop action says) and the log closed."""
        self._last_good = theta0.copy()
        self._torque_on = False
        stop: StopReason | None = None
        self.realtime = request_realtime(LOOP_PRIORITY)
        self._event("realtime", policy=self.realtime.policy, detail=self.realtime.detail,
                    kernel_preemption=kernel_preemption(), cpus=placement())
        try:
            if self._estop.is_set():  # E-stop before torque-on: nothing is switched on or moved
                stop = SafetyMonitor.estop(f"{self._estop_reason or 'E-stop'} (before any motion)",
                                           self._now(), 0)
                self._event("stop", kind=stop.kind, action="none", detected_t=stop.t,
                            exit_code=int(stop.exit_code),
                            notes=["this run switched no torque on and sent no goal: the "
                                   "servos keep what they did before it (holding, if a "
                                   "run before left them so)"])
            else:
                stop = self._preflight(theta0)
            if stop is None:
                stop = loop()
        except KeyboardInterrupt:
            stop = SafetyMonitor.estop("interrupted (Ctrl-C)", self._now(), len(self.samples))
            self._apply_stop(stop, self._hold_target(self._last_good), deadline=None)
        except BaseException as exc:
            # Leave the robot safe and the log complete, then re-raise.
            spm = isinstance(exc, SpmError)
            msg = exc.message if isinstance(exc, SpmError) else f"internal error: {exc!r}"
            if self._torque_on:
                with contextlib.suppress(Exception):
                    self._apply_stop(SafetyMonitor.estop(msg, self._now(), len(self.samples)),
                                     self._hold_target(self._last_good), deadline=None)
            code = exc.exit_code if isinstance(exc, SpmError) else ExitCode.INTERNAL
            self._finish("refused" if spm and not self.samples else "error", code, msg, None)
            raise
        finally:
            release_realtime(self.realtime)
        self._release_watchdog()
        if stop is None:
            msg = done()
            self._event("done", message=msg)
            return self._finish("completed", ExitCode.OK, msg, None)
        if stop.kind == "estop" and self._estop_by_signal and not self.samples:  # nothing moved
            msg = stop.message if "before any motion" in stop.message else \
                f"{stop.message} (before any motion)"
            return self._finish("interrupted", ExitCode.INTERRUPTED, f"{msg}; nothing moved", stop)
        return self._finish("stopped", stop.exit_code, stop.message, stop)

    def _loop(self, refs: F, phases: list[str], regions: list[bool], theta0: F,
              settle: bool = False, sent: F | None = None) -> StopReason | None:
        """Cycle through the verified references; ``sent`` (same shape): what goes to the
        servos instead, the references plus the load's offset (:mod:`.load_offsets`)."""
        st = self._loop_state(theta0)
        out = refs if sent is None else sent
        for k in range(len(refs)):
            stop = self._cycle(st, k, refs[k], phases[k], regions[k], sent=out[k])
            if stop is not None:
                return stop
        return (self._settle(st, len(refs), refs[-1], out[-1] - refs[-1]) if settle else None)

    def _settle(self, st: LoopState, k0: int, goal: F, offset: F | None = None
                ) -> StopReason | None:
        """Periods at the plan's goal with the goal sent shifted by the measured offset
        (:mod:`spm_console.motion.goals.settle`), each shifted goal where the safety monitor
        lets the measured position be, with the tolerance and a tick to spare (a joint that
        slips onto its shifted goal stays clear of a region stop): within the servo limits,
        in the certified set relaxed by the region margin (the goal itself is in the strict
        set, as every reference)."""
        certified = self.verifier.certified
        spare = float(self.profile.settle.tolerance_deg) + servo_tick_deg(self.profile)
        half_width = min(certified.step_deg, st.safety.region_half_width_deg + spare)

        def allowed(theta: F) -> bool:
            inside = bool(np.all(theta >= self.lo) and np.all(theta <= self.hi))
            return inside and bool(certified.contains(theta[None], half_width)[0])

        s = Settling(self.profile.settle, goal, allowed)
        used = 0
        for j in range(settle_periods(self.profile.settle, self.ts)):
            sent = None if offset is None else np.clip(s.reference + offset, self.lo, self.hi)
            stop = self._cycle(st, k0 + j, s.reference, "settle", True, sent=sent)
            if stop is not None:
                return stop
            used = j + 1
            s.update(self.samples[-1].measured_deg)
            if s.settled:
                break
        last = next((x.measured_deg for x in reversed(self.samples) if x.read_ok), goal)
        error = goal - last  # the last position read (a lost read says nothing)
        self._event("settle", settled=s.settled, periods=used, shift_deg=s.shift,
                    error_deg=error, refused_shifts=s.refused)
        law = self.profile.settle
        self.settle_outcome = SettleOutcome(
            s.settled, (float(error[0]), float(error[1]), float(error[2])),
            float(law.tolerance_deg), float(law.duration_s), s.refused)
        return None

    def _loop_state(self, theta0: F) -> LoopState:
        """Filters, predictors and the safety monitor of a run starting at rest at θ0; sets the
        first deadline (t0) and tells ``on_start``."""
        safety = SafetyMonitor(self.profile, self.verifier.certified, emulated=self.emulated,
                               simulated_time=self.simulated_time)
        self.safety = safety
        st = LoopState(
            safety=safety,
            kf=KalmanVelocity(self.model, theta0, self.profile.estimation.measurement_noise_deg,
                              self.profile.estimation.process_noise_deg),
            fd=FiniteDifference(self.ts),
            pred=ModelPredictor(self.model, theta0),  # ideal grid: the plan's 'simulated' curve
            pred_t=ModelPredictor(self.model, theta0),  # actual write/read times: safety's model
            last_good=theta0.copy(), t_state=self.clock(), u_prev=theta0)
        self.t0 = self.clock() + 0.002
        st.t_state = self.clock()  # at rest at θ0, goal θ0: any start time works
        if self.on_start is not None:
            self.on_start()
        return st

    def _cycle(self, st: LoopState, k: int, ref: F, phase: str, region: bool,
               target: F | None = None, sent: F | None = None,
               target_clamp_deg: float | None = None) -> StopReason | None:
        """Cycle k: wait for its deadline, write ``ref`` (or ``sent``: ``ref`` plus the load's
        offset; the models run on ``ref``), read, filter, check, publish; the stop (already
        applied) or None."""
        deadline = self.t0 + k * self.ts
        self._wait_until(deadline)
        t_start = self.clock()
        t = t_start - self.t0
        if self._estop.is_set():
            estop = SafetyMonitor.estop(self._estop_reason, t, k)
            # woken before this cycle's deadline: the repeat goes out at that deadline
            repeat_at = deadline if t_start < deadline else deadline + self.ts
            self._apply_stop(estop, self._hold_target(st.last_good), repeat_at)
            return estop
        t_write = self.clock()
        goal = ref if sent is None else sent
        z, retries, detail, t_read = self._cycle_io(goal)
        t_end = self.clock()
        bus_s = t_end - t_start
        t_meas = t_read if z is not None else t_end
        # θ*(k−1) held until the write, θ*(k) from then to the measurement
        spans = [(t_write - st.t_state, st.u_prev), (t_meas - t_write, ref)]
        st.t_state, st.u_prev = t_meas, ref
        if z is not None:
            st.last_good = self._last_good = z
        filt, vel = st.kf.step_timed(spans, z)
        fdv = st.fd.step(z, t_read if z is not None else None)
        st.pred_t.propagate(spans)
        p_pos, p_vel = st.pred.position_deg, st.pred.velocity_degps
        p_read = st.pred_t.position_deg  # the model when the position was read
        safety = st.safety
        stop: StopReason | None = safety.comm(z is not None, retries, t, k, detail)
        t_hw = self.clock()
        if stop is None and (self._alerted() or k % self.hw_poll_every == 0):
            stop = self._poll_hw(safety, t, k)
        t_pos = self.clock()
        if stop is None and z is not None:
            stop = safety.position(z, p_read, region, t, k)
        meas = z if z is not None else np.full(3, np.nan)
        err = float(np.abs(meas - p_read).max()) if z is not None else float("nan")
        sample = Sample(t=t, k=k, phase=phase, reference_deg=goal, measured_deg=meas,
                        predicted_deg=p_pos, predicted_velocity_degps=p_vel,
                        filtered_deg=filt, velocity_degps=vel, fd_velocity_degps=fdv.copy(),
                        tracking_error_deg=err, bus_s=bus_s, late_s=t_start - deadline,
                        read_offset_s=(t_read - deadline) if z is not None else float("nan"),
                        retries=retries,
                        stale_replies=stale_replies(self.bus) - self._stale0, target_deg=target,
                        target_clamp_deg=target_clamp_deg)
        self._publish(sample)
        t_done = self.clock()
        if t_done - deadline > SLOW_CYCLE * self.ts:  # where the period went (diagnostics)
            self._event("slow_cycle", k=k, late_ms=round((t_start - deadline) * 1e3, 3),
                        bus_ms=round(bus_s * 1e3, 3), filter_ms=round((t_hw - t_end) * 1e3, 3),
                        hw_poll_ms=round((t_pos - t_hw) * 1e3, 3),
                        checks_ms=round((t_done - t_pos) * 1e3, 3))
        if stop is not None:
            self._apply_stop(stop, self._hold_target(st.last_good), deadline + self.ts)
            return stop
        st.pred.advance(ref)
        return None

    def _publish(self, sample: Sample) -> None:
        self.samples.append(sample)
        if self.log is not None:
            self.log.sample(sample)
        if self.on_sample is not None:
            try:
                self.on_sample(sample)
            except Exception as exc:  # a UI bug must not stop the servo loop
                self._event("callback_error", error=repr(exc))
                self.on_sample = None

    def _finish(self, outcome: str, code: ExitCode, message: str,
                stop: StopReason | None) -> ExecutionResult:
        safety = getattr(self, "safety", None)
        timing = getattr(self, "stop_timing", None)
        stats = replace(
            run_stats(self.samples, self.ts),
            stale_replies=stale_replies(self.bus) - getattr(self, "_stale0", 0),
            comm_retries=0 if safety is None else safety.comm_retries,
            comm_failed_cycles=0 if safety is None else safety.comm_failed_cycles,
            stop=None if stop is None else StopTiming(stop.kind, stop.t, stop.k, *(timing or ())),
            model=model_health(self.samples, self.profile.servo.residual_bound_deg,
                               servo_tick_deg(self.profile)))
        if self.log is not None:
            self.log.finish(outcome, int(code), message, stats.to_dict())
        final = next((s.measured_deg for s in reversed(self.samples) if s.read_ok), None)
        return ExecutionResult(
            outcome="completed" if outcome == "completed" else "stopped",
            exit_code=code, message=message,
            log_dir=self.log.path if self.log is not None else None,
            stop=stop, final_deg=final, stats=stats,
            realtime="" if self.realtime.policy == "normal" and not self.samples
            else self.realtime.detail,
            realtime_granted=self.realtime.policy == "SCHED_FIFO",
            settle=self.settle_outcome,
        )
