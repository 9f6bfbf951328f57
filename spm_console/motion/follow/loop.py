"""Live following in the servo loop: the wrist tracks a target that may change at any time.

Every period k, after the cycle's write and read (:meth:`Executor._cycle`), the loop

1. predicts the Kalman state (θ̂, θ̇̂) at the next deadline under the reference just sent
   (exact ZOH over the time left in the period);
2. re-plans from it with :class:`~spm_console.core.planning.follow.solver.FollowSolver` (MVN cost,
   a tracking term and the target as terminal state when reachable within the 1 s horizon;
   speed bound, servo limits and one region of the workspace's cover — P, or the region the
   wrist has moved on to, :mod:`.follow_regions`; warm-started) toward the feed's targets (a
   timed list gives a preview over the horizon), or toward the overlap with the next region
   when the target lies in another region of the cover;
3. **verifies** the new plan itself before adopting it — its continuous motion from the
   predicted state (10 points per period over the horizon, held at its end) certified by
   this profile's workspace, speed within ``limits.vmax_degps`` + 10 % between samples (a
   joint predicted faster than that may not get faster), references inside the servo limits,
   no reference step above 10° — the rules the runtime applies to every plan
   (:mod:`spm_console.motion.plan_check`);
4. sends the adopted plan's next reference at the next deadline. A solve that fails, runs past
   :data:`SOLVE_BUDGET_S` or is refused by the check is not used: the previous (verified)
   plan's next reference goes out instead (held at its rest point past its horizon), and the
   miss is counted. So every reference streamed comes from a verified plan.

Targets in no region of the cover are projected to the nearest point of the current region
(the solver's projection) and counted as clamped; the wrist never chases them through
uncertified space. The run ends when the feed
is finished (timed list over, or the live source ended) and the wrist has settled on the last
target; E-stop and every safety stop act as in any run. Degrees, seconds.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import servo_tick_deg
from spm_console.core.plan_rules import FOLLOW_RULES, MotionCheck, check_motion
from spm_console.core.planning.follow.osqp_follow import FollowSettings
from spm_console.core.planning.follow.result import FollowResult
from spm_console.core.planning.follow.solver import TARGET_REFUSED, FollowSolver
from spm_console.core.planning.follow.target import TargetProjector
from spm_console.core.planning.follow.tolerance import FOLLOW_TOL_DEG
from spm_console.core.polytope.region import Region
from spm_console.core.servo.model import exact_step
from spm_console.errors import BadInputError
from spm_console.formatting import fmt_deg
from spm_console.motion.cycle.state import LoopState
from spm_console.motion.executor import Executor
from spm_console.motion.follow.regions import (
    MOVE_IN,
    RegionHopper,
    follow_regions,
    follow_start,
)
from spm_console.motion.follow.target_feed import TargetFeed
from spm_console.motion.goals.load_offsets import LoadTracker, load_model, step_limited
from spm_console.motion.safety import SafetyMonitor, StopReason
from spm_console.motion.segments import ExecutionResult
from spm_console.motion.stats import stale_replies

F = NDArray[np.float64]

#: Receding horizon, samples (1 s at Ts = 20 ms).
HORIZON = 50
#: Time a re-plan may take in the loop before its answer is dropped, s (OSQP's time limit).
SOLVE_BUDGET_S = 0.012
#: Settled on the final target: within this, deg, …
SETTLE_TOL_DEG = 0.2
#: … slower than this, deg/s, …
SETTLE_SPEED_DEGPS = 2.0
#: … for this long, s.
SETTLE_S = 0.3
#: A finished feed ends the run at the latest this long after it finished, s.
SETTLE_TIMEOUT_S = 10.0
#: A wrist just beyond the grid first moves this many servo ticks inside the region.
APPROACH_DEPTH_TICKS = 2.0


@dataclass(frozen=True)
class FollowStats:
    """How the re-planning went (logged as the ``follow`` event, returned to the client)."""

    solves: int
    adopted: int
    """Plans that passed the runtime's check and were used."""
    misses: int
    """Solves not used (failed or past the budget): the previous plan went on."""
    refused: int
    """Plans the runtime's check refused."""
    clamped: int
    """Periods whose target lay outside the region (projected)."""
    deadman_trips: int
    solve_ms_p50: float
    solve_ms_p99: float
    solve_ms_max: float
    region_switches: int = 0
    """Times the follower moved on to the next region of the cover."""
    approach_cycles: int = 0
    """Periods spent moving in from just beyond the grid before the first re-plan."""

    def to_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}


def _aimed(feed: TargetFeed, targets: F, goal: F | None) -> F:
    """What the solver heads for: the overlap with the next region (``goal``), else the
    feed's target (with its preview for a timed feed)."""
    if goal is not None:
        return np.asarray(goal, float)
    return targets if feed.timed else targets[0]


class Follower(Executor):
    """An :class:`Executor` whose references are re-planned every period toward a target."""

    def follow(self, feed: TargetFeed, theta0_deg: F | None = None) -> ExecutionResult:
        """Follow ``feed`` from where the wrist is until it is finished and settled."""
        self.t0 = self.clock()
        self._stale0 = stale_replies(self.bus)
        theta0 = self.read_initial() if theta0_deg is None else np.asarray(theta0_deg, float)
        start = self._start(theta0)
        graph = follow_regions(self.verifier.ws, start)  # BadInputError: why not
        regions = graph.regions
        self.hopper = RegionHopper(graph, start)
        # just beyond the grid: the wrist first moves in, plans start from where it moves to
        approach = (None if start is theta0
                    else self._approach_point(theta0, regions[self.hopper.current]))
        begin = theta0 if approach is None else approach
        vmax = self.profile.limits.vmax_degps
        # one solver per region, factored before torque-on (10–25 ms each: not in the loop)
        self.solvers = [FollowSolver(self.model, r, vmax, HORIZON, self.lo, self.hi,
                                     settings=FollowSettings(time_limit_s=SOLVE_BUDGET_S),
                                     lead_max_deg=self.profile.servo.linear_range_deg)
                        for r in regions]
        targets, _ = feed.targets(0.0, self.ts, HORIZON, theta0)
        idx, goal = self.hopper.aim(begin, targets[-1])
        first = self.solvers[idx].solve(begin, np.zeros(3), _aimed(feed, targets, goal),
                                        warm=False, timed=False)  # cold, before torque-on
        if not first.ok or not self._plan_ok(first, begin, np.zeros(3), begin):
            raise BadInputError(f"live following cannot start from θ = "
                                f"{fmt_deg(theta0)}: {first.reason or first.status}")
        self._times: list[float] = []
        self._refused_target = ""
        self._counts = {"solves": 0, "adopted": 0, "misses": 0, "refused": 0, "clamped": 0,
                        "approach": 0}
        self._event("start", theta0_deg=theta0, mode="follow", live=feed.live,
                    horizon=HORIZON, budget_ms=SOLVE_BUDGET_S * 1e3, deadman_s=feed.deadman_s,
                    region=self.hopper.current, regions=len(self.solvers),
                    grown_around_start=graph.grown,
                    **({} if approach is None else {"start_deg": approach}))
        result = self._guarded(theta0, lambda: self._follow_loop(feed, theta0, first, approach),
                               lambda: f"followed for {len(self.samples) * self.ts:.2f} s")
        return result

    def stats(self, feed: TargetFeed) -> FollowStats:
        ms = np.asarray(self._times, float) * 1e3

        def pct(q: float) -> float:
            return float(np.percentile(ms, q)) if ms.size else float("nan")

        c = self._counts
        return FollowStats(c["solves"], c["adopted"], c["misses"], c["refused"], c["clamped"],
                           feed.deadman_trips, pct(50), pct(99),
                           float(ms.max()) if ms.size else float("nan"), self.hopper.switches,
                           c["approach"])

    def _start(self, theta0: F) -> F:
        """Where the plans start (:func:`follow_start`): θ0, or the point just inside the grid's
        box when the wrist stands a little beyond it — then only if the executor's region
        check (with its margin) accepts θ0, so that the move in is checked like any cycle."""
        start = follow_start(self.verifier.ws, theta0, self.start_tolerance_deg,
                             servo_tick_deg(self.profile))
        if np.array_equal(start, theta0):
            return theta0
        certified = self.verifier.certified
        half = SafetyMonitor(self.profile, certified).region_half_width_deg
        if not bool(certified.contains(theta0, half)):
            raise BadInputError(
                f"the wrist is at θ = {fmt_deg(theta0)}, beyond the workspace grid and outside "
                f"the certified set even with the region margin "
                f"({self.profile.safety.region_margin_deg:.2f}°): {MOVE_IN}")
        return start

    def _approach_point(self, theta0: F, region: Region) -> F:
        """The point of ``region`` nearest θ0 at least :data:`APPROACH_DEPTH_TICKS` servo ticks
        inside it (the servo settles on a tick, the state must end up inside); BadInputError
        when it lies farther than the approach tolerance."""
        depth = APPROACH_DEPTH_TICKS * servo_tick_deg(self.profile)
        point, _ = TargetProjector(region, self.lo, self.hi, depth).project(theta0)
        gap = float(np.abs(point - theta0).max())
        if gap > self.start_tolerance_deg:
            raise BadInputError(
                f"the wrist is at θ = {fmt_deg(theta0)}, beyond the workspace grid; the nearest "
                f"point a region holds is {gap:.2f}° away (more than the approach tolerance, "
                f"{self.start_tolerance_deg:g}°): {MOVE_IN}")
        return point

    def _inside(self, theta: F) -> bool:
        """θ (deg) is in the current region and certified: plans may start from it."""
        region = self.hopper.regions[self.hopper.current]
        return bool(region.contains(theta, tol=FOLLOW_TOL_DEG)) and bool(
            self.verifier.certified.contains(theta))

    # ------------------------------------------------------------------ the loop
    def _follow_loop(self, feed: TargetFeed, theta0: F, first: FollowResult,
                     approach: F | None = None) -> StopReason | None:
        """The servo loop; ``approach``: the point plans start from when the wrist stands just
        beyond the grid (:meth:`_start`): it is the reference until the predicted state is in
        the region, then re-planning begins."""
        st: LoopState = self._loop_state(theta0)
        plan, j = first, 0
        ref = plan.reference_at(0) if approach is None else approach
        settled_since: float | None = None
        finished_at: float | None = None
        updates = 0  # targets that arrived before the start are logged with cycle 0
        load = load_model(self.profile)
        tracker = None
        if load is not None:
            try:
                tracker = LoadTracker(self.profile, load, theta0)
            except ValueError as exc:  # no FK from home to θ0: follow without the offset
                self._event("load_offsets_off", reason=str(exc))
        th_next, om_next = theta0, np.zeros(3)
        sent: F | None = None
        feed.arm()  # the deadman counts from here: the set-up is not the source's silence
        k = 0
        while True:
            asked = feed.now(k * self.ts, st.last_good)  # logged beside the reference
            if tracker is not None:  # the load's offset where the model is headed
                d = tracker.offset(th_next, om_next)
                sent = step_limited(sent, ref if d is None else ref + d, self.lo, self.hi)
            stop = self._cycle(st, k, ref, "follow", True, target=asked, sent=sent,
                               target_clamp_deg=plan.clamp_deg if plan.clamped else 0.0)
            if stop is not None:
                return stop
            s = self.samples[-1]
            t_next = (k + 1) * self.ts
            th, om = self._predict(s.filtered_deg, s.velocity_degps, ref, s.read_offset_s)
            th_next, om_next = th, om
            if feed.updates != updates:  # a live target arrived: logged with the cycle it meets
                updates = feed.updates
                self._event("target", k=k, theta_deg=feed.final(s.filtered_deg))
            targets, held = feed.targets(t_next, self.ts, HORIZON, s.filtered_deg)
            if held and feed.deadman_trips != self._counts.get("deadman_logged", 0):
                self._counts["deadman_logged"] = feed.deadman_trips
                self._event("deadman", k=k, hold_deg=targets[0], silent_s=feed.deadman_s)
            if approach is not None and not self._inside(th):
                ref = approach  # moving in: no plan starts outside the region
                self._counts["approach"] += 1
            else:
                if approach is not None:
                    approach = None
                    self._event("approached", k=k, theta_deg=th)
                plan, j, ref = self._replan(feed, targets, th, om, ref, plan, j, k)
            # the end: a finished feed, the wrist settled on the (projected) last target
            if feed.finished(t_next):
                finished_at = t_next if finished_at is None else finished_at
                goal = plan.target_deg
                near = (float(np.abs(s.filtered_deg - goal).max()) <= SETTLE_TOL_DEG
                        and float(np.abs(s.velocity_degps).max()) <= SETTLE_SPEED_DEGPS)
                settled_since = (settled_since if settled_since is not None else t_next) if near else None
                if settled_since is not None and t_next - settled_since >= SETTLE_S:
                    break
                if t_next - finished_at >= SETTLE_TIMEOUT_S:
                    self._event("settle_timeout", target_deg=goal, wrist_deg=s.filtered_deg)
                    break
            k += 1
        self._event("follow", **self.stats(feed).to_dict())
        return None

    def _replan(self, feed: TargetFeed, targets: F, th: F, om: F, ref: F, plan: FollowResult,
                j: int, k: int) -> tuple[FollowResult, int, F]:
        """Step 2–4 of the module docstring: (plan in use, its sample index, next reference)."""
        t0 = time.perf_counter()
        before = self.hopper.switches
        idx, goal = self.hopper.aim(th, targets[-1])
        if self.hopper.switches != before:  # inside the next region: plan there from now on
            self.solvers[idx].reset()
            self._event("region", k=k, region=idx, switches=self.hopper.switches)
        res = self.solvers[idx].solve(th, om, _aimed(feed, targets, goal), elapsed=1,
                                      previous_reference_deg=ref)
        self._times.append(time.perf_counter() - t0)
        if res.detail == TARGET_REFUSED and res.reason != self._refused_target:
            self._refused_target = res.reason  # logged once per target: the plan in use goes on
            self._event("target_refused", k=k, reason=res.reason, theta_deg=res.requested_deg)
        self._counts["solves"] += 1
        self._counts["clamped"] += int(res.clamped)
        j += 1
        if res.ok and res.seconds <= SOLVE_BUDGET_S:
            if self._plan_ok(res, th, om, ref):
                plan, j = res, 0
                self._counts["adopted"] += 1
            else:
                self._counts["refused"] += 1
        else:
            self._counts["misses"] += 1
        return plan, j, np.clip(plan.reference_at(j), self.lo, self.hi)

    def _predict(self, theta: F, omega: F, ref: F, read_offset_s: float) -> tuple[F, F]:
        """The model state at the next deadline, from the Kalman estimate at the read instant
        under the reference just sent."""
        dt = self.ts - (read_offset_s if np.isfinite(read_offset_s) else 0.0)
        Phi, Gam = exact_step(self.model.dynamics, max(dt, 0.0))
        th = Phi[0, 0] * theta + Phi[0, 1] * omega + Gam[0] * ref
        om = Phi[1, 0] * theta + Phi[1, 1] * omega + Gam[1] * ref
        return np.asarray(th, float), np.asarray(om, float)

    def _plan_ok(self, res: FollowResult, theta: F, omega: F, prev_ref: F) -> bool:
        """The runtime's own check of a re-planned horizon (see the module docstring): its
        motion from the predicted state (θ deg, θ̇ deg/s), held at θ(H) one more sample."""
        return self._plan_check(res, theta, omega, prev_ref).ok

    def _plan_check(self, res: FollowResult, theta: F, omega: F, prev_ref: F) -> MotionCheck:
        """:meth:`_plan_ok` with the first violation and what was checked: the executor's
        rules (:func:`~spm_console.core.plan_rules.check_motion`) as
        :data:`~spm_console.core.plan_rules.FOLLOW_RULES` apply them."""
        refs = np.vstack([res.reference_deg, res.reference_at(res.horizon)[None]])
        # a joint already faster than the bound (an estimate disturbed by a late read) only
        # needs a plan that does not make it faster: refusing every plan would keep the old one
        return check_motion(self.model.dynamics, self.ts, np.column_stack([theta, omega]), refs,
                            self.lo, self.hi, self.profile.limits.vmax_degps,
                            self.verifier.certified, rules=FOLLOW_RULES,
                            previous_reference_deg=prev_ref, speed_floor_degps=np.abs(omega),
                            lead_max_deg=self.profile.servo.linear_range_deg)
