"""Live following: a receding-horizon version of the MVN problem (30), solved every servo period.

Units: θ, θ*, targets in degrees; θ̇ in deg/s; time in seconds; horizon H in samples of Ts.

Problem solved by :meth:`FollowSolver.solve` from the current state θ(0), θ̇(0) (e.g. the
Kalman estimate) toward the target t (one (3,) point, or a preview t(1..H))::

    min  Σ_{k=1..H} ‖θ̇(k)‖²  +  w Σ_{k=1..H} ‖θ(k) − t(k)‖²  +  ρ ‖θ(H) − t(H)‖₁
    s.t. servo dynamics (28) from θ(0), θ̇(0);  |θ̇(k)| ≤ v_max (k = 1..H);  θ̇(H) = 0;
         A θ(k) ≤ b (k = 1..H);  lo ≤ θ*(k) ≤ hi (k = 0..H−1);  lo ≤ θ(H) ≤ hi.

* The first term is the MVN cost of (30). The L1 terminal term is an *exact penalty*: when
  the target can be reached and held at rest within the horizon (and ρ exceeds the terminal
  constraint's multiplier) the solution has θ(H) = t exactly — status ``"reached"``, the
  target as terminal state; otherwise it is a terminal cost pulling θ(H) as close as the
  speed bound and the region allow — status ``"tracking"``. One QP covers both cases, so
  there is no infeasible first attempt to pay for in the loop.
* The stage term (weight w, 1/s²; √w is roughly the tracking bandwidth in rad/s) makes the
  wrist get there early rather than "in one horizon": with w = 0 and a fixed target the
  receding plan would re-spread the remaining motion over H samples every period and close
  the gap only like e^(−t/(H·Ts)). w = 0 gives the pure MVN terminal problem (tests).
* θ̇(H) = 0 (rest at the horizon) makes the previous plan, shifted by a sample and held at
  θ(H), feasible again for the next solve (recursive feasibility) — that shifted plan is
  also the warm start. The region and speed rows are tightened by ``margin_deg`` /
  ``speed_margin_degps`` so that the solver's tolerance never puts a sample outside the true
  region; every result is then re-simulated through the exact model and checked against the
  true (untightened) constraints before it is returned as ok.
* Only the samples are constrained (as in (30) with K = 1), not the motion between them
  (benchmarks/bench_follow.py counts the exact continuous response outside P).
* By default the QP is solved condensed onto the references by DAQP, a dense dual
  active-set solver (:mod:`spm_console.core.planning.follow.dense`): exact on its active set,
  factored once per solver, each solve starting from the previous active set. When it gives
  no answer that passes the check (or says infeasible), OSQP on the sparse QP decides.
* OSQP runs at tolerance 1e-3 with polishing (exact when it finds the active set); only
  when that answer is unpolished or fails the check does it go on, from the same iterate,
  at 1e-4 and then 1e-6 (``FollowSettings.tolerances``), within ``time_limit_s`` if set.
* Targets are *projected* onto the nearest point (L2) of the region tightened by twice
  ``margin_deg`` ∩ the servo limits box (a 3-variable QP, only for targets outside it), so
  a terminal target never sits on a constraint the QP can only meet to its tolerance. The
  result says ``clamped`` when a given target was outside the true region or the limits
  (``clamp_deg``: how far it moved; a target inside but within 2·margin_deg of a face is
  moved by at most that and not reported as clamped).
* An initial state outside the region is refused (status ``"infeasible"``, with the reason)
  without calling the solver; so is a state from which the constraints cannot be met.

For a 50 Hz loop: build the solver once, call :meth:`solve` every period with the newest
state and target (warm start is automatic; pass ``elapsed`` when periods were skipped), stream
``result.first_reference_deg``; when a result is not ok (or late), keep streaming the last
good result's :meth:`FollowResult.reference_at` and count the miss.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from spm_console.core.planning.follow.daqp_follow import DAQP_OPTIMAL, DAQP_TIME_LIMIT, DaqpFollow
from spm_console.core.planning.follow.dense import (
    DENSE_MAX_ENTRIES,
    build_dense,
    dense_entries,
)
from spm_console.core.planning.follow.osqp_follow import (
    FollowSettings,
    FollowWeights,
    OsqpFollow,
    Solved,
    out_of_time,
)
from spm_console.core.planning.follow.qp import (
    FollowLayout,
    FollowMatrices,
    build,
    fill_bounds,
    linear_cost,
)
from spm_console.core.planning.follow.result import FollowResult, FollowStatus
from spm_console.core.planning.follow.target import ProjectionError, TargetProjector
from spm_console.core.planning.follow.tolerance import FOLLOW_TOL_DEG
from spm_console.core.planning.qp_build import PLAN_STEP_DEG
from spm_console.core.polytope.region import Region
from spm_console.core.servo.model import ServoModel
from spm_console.errors import BadInputError
from spm_console.formatting import fmt_deg

F = NDArray[np.float64]


#: ``FollowResult.detail`` of a result refused because its target has no projection.
TARGET_REFUSED = "target refused"
#: θ(H) within this of the terminal target counts as reached, deg (a tenth of a servo tick).
REACH_TOL_DEG = 1e-2
RULE_MARGIN_DEG = 0.01
"""The QP holds the runtime's reference step and lead this far inside their bounds: its
loosest pass answers to 1e-3, and an answer over a bound by that is one the runtime refuses."""


@dataclass
class _Warm:
    x: F
    y: F


@dataclass
class FollowSolver:
    """Receding-horizon follow QP built once for a servo model, a region and a horizon.

    ``region``: A θ ≤ b, θ in degrees; ``vmax_degps``: speed bound; ``horizon``: H samples
    (default 50 = 1 s at Ts = 0.02 s); ``ref_lo_deg`` / ``ref_hi_deg``: servo limits on the
    references (and on the held terminal state); ``margin_deg`` / ``speed_margin_degps``:
    tightening of the region / speed rows inside the QP.
    """

    model: ServoModel
    region: Region
    vmax_degps: float
    horizon: int = 50
    ref_lo_deg: F | None = None
    ref_hi_deg: F | None = None
    weights: FollowWeights = field(default_factory=FollowWeights)
    settings: FollowSettings = field(default_factory=FollowSettings)
    margin_deg: float = 0.05
    speed_margin_degps: float = 0.25
    lead_max_deg: float | None = None
    """The servo's linear range: largest |θ*(k) − θ(k)|, deg (None: none)."""

    def __post_init__(self) -> None:
        if not (np.isfinite(self.vmax_degps) and self.vmax_degps > self.speed_margin_degps):
            raise BadInputError(f"vmax must be a positive speed in deg/s, got {self.vmax_degps}")
        if int(self.horizon) != self.horizon or not 2 <= self.horizon <= 1000:
            raise BadInputError(f"horizon must be an integer in 2..1000 samples, got {self.horizon}")
        if not self.settings.tolerances:
            raise BadInputError("follow settings: give at least one tolerance")
        if self.weights.track < 0 or self.weights.terminal <= 0:
            raise BadInputError("follow weights: track must be ≥ 0 and terminal > 0")
        lo = np.full(3, -np.inf) if self.ref_lo_deg is None else np.broadcast_to(
            np.asarray(self.ref_lo_deg, float), (3,)).copy()
        hi = np.full(3, np.inf) if self.ref_hi_deg is None else np.broadcast_to(
            np.asarray(self.ref_hi_deg, float), (3,)).copy()
        if np.any(lo >= hi):
            raise BadInputError(f"reference limits must satisfy lo < hi, got {lo} and {hi}")
        self._lo, self._hi = lo, hi
        lead = np.inf if self.lead_max_deg is None else max(
            float(self.lead_max_deg) - RULE_MARGIN_DEG, 0.5 * float(self.lead_max_deg))
        rows = (self.model, self.region, self.vmax_degps, self.horizon, lo, hi,
                self.weights.track, self.margin_deg, self.speed_margin_degps,
                PLAN_STEP_DEG - RULE_MARGIN_DEG, lead)
        self._rows = rows
        self._mats_built: FollowMatrices | None = None
        self._projector = TargetProjector(self.region, lo, hi, 2.0 * self.margin_deg)
        dense = self.settings.backend == "daqp" and dense_entries(
            self.horizon, self.region.halfspaces) <= DENSE_MAX_ENTRIES
        self._daqp = DaqpFollow(build_dense(*rows), self.weights.terminal) if dense else None
        self._daqp_warm = False
        self._warm: _Warm | None = None
        self._osqp_solver: OsqpFollow | None = None
        if self._daqp is None:
            self._osqp_solver = self._osqp

    @property
    def _mats(self) -> FollowMatrices:
        """The sparse QP (OSQP's), assembled when first needed."""
        if self._mats_built is None:
            self._mats_built = build(*self._rows)
        return self._mats_built

    @property
    def _osqp(self) -> OsqpFollow:
        """OSQP on the sparse QP, set up when first needed."""
        if self._osqp_solver is None:
            self._osqp_solver = OsqpFollow(self._mats, self.model, self.settings, self.weights,
                                           self._check, self._lo, self._hi)
        return self._osqp_solver

    @property
    def layout(self) -> FollowLayout:
        return self._mats.layout

    @property
    def ts(self) -> float:
        return self.model.ts

    def reset(self) -> None:
        """Forget the previous solution (the next solve starts cold)."""
        self._warm = None
        self._daqp_warm = False

    def project(self, target_deg: F) -> tuple[F, float]:
        """(nearest admissible point, distance moved in deg) for a (3,) target."""
        return self._projector.project(np.asarray(target_deg, float))

    def solve(self, theta_deg: F, omega_degps: F, target_deg: F, elapsed: int = 1,
              warm: bool = True, timed: bool = True,
              previous_reference_deg: F | None = None) -> FollowResult:
        """Re-plan from the state θ(0) = ``theta_deg``, θ̇(0) = ``omega_degps`` (3,) toward
        ``target_deg``: (3,) held over the horizon, or (H, 3) a preview t(1..H).

        ``elapsed``: periods since the previous solve (the warm start is shifted by that);
        ``warm=False``: solve cold (from OSQP's zero start); ``timed=False``: without the
        settings' ``time_limit_s`` (a solve before the motion starts, where nothing waits);
        ``previous_reference_deg``: the reference in use, from which the first one may step
        at most the runtime's largest step (None: θ(0), a wrist at rest)."""
        t0 = time.perf_counter()
        H = self.horizon
        th0 = np.asarray(theta_deg, float).reshape(-1)
        om0 = np.asarray(omega_degps, float).reshape(-1)
        tg = np.asarray(target_deg, float)
        if th0.shape != (3,) or om0.shape != (3,) or not (np.isfinite(th0).all() and np.isfinite(om0).all()):
            raise BadInputError("follow: the state must be three finite angles (deg) and speeds (deg/s)")
        if tg.shape not in ((3,), (H, 3)) or not np.isfinite(tg).all():
            raise BadInputError(f"follow: the target must be (3,) or ({H}, 3) finite angles in degrees")
        requested = tg if tg.ndim == 1 else tg[-1]
        rows = np.broadcast_to(tg, (H, 3))
        try:
            targets, moved = self._project_rows(rows)
        except ProjectionError as exc:  # refused: the plan in use goes on, no substitute
            self._warm = None
            empty = np.zeros((0, 3))
            return FollowResult(
                status="failed", reference_deg=empty, position_deg=empty, velocity_degps=empty,
                requested_deg=requested.copy(), target_deg=th0.copy(), clamped=False,
                clamp_deg=float("inf"), cost=float("inf"), terminal_error_deg=float("inf"),
                seconds=time.perf_counter() - t0, iterations=0, warm=False, reason=exc.message,
                detail=TARGET_REFUSED)
        terminal = targets[-1]
        clamped = moved > 0.0 and self._outside(tg.reshape(-1, 3))

        def refuse(status: FollowStatus, reason: str, detail: str = "", it: int = 0,
                   used_warm: bool = False) -> FollowResult:
            empty = np.zeros((0, 3))
            return FollowResult(
                status=status, reference_deg=empty, position_deg=empty, velocity_degps=empty,
                requested_deg=requested.copy(), target_deg=terminal, clamped=clamped,
                clamp_deg=moved, cost=float("inf"), terminal_error_deg=float("inf"),
                seconds=time.perf_counter() - t0, iterations=it, warm=used_warm, reason=reason,
                detail=detail)

        viol = float(self.region.violation_deg(th0))
        if viol > FOLLOW_TOL_DEG:
            self.reset()
            return refuse("infeasible", f"the state θ = {fmt_deg(th0, 3)} is outside the "
                          f"region by {viol:.3g}°: following starts only inside it")
        prev = None if previous_reference_deg is None else np.asarray(
            previous_reference_deg, float).reshape(3)
        run: Solved | None = None
        if self._daqp is not None:
            used_warm = warm and self._daqp_warm
            run = self._run_daqp(th0, om0, targets, th0 if prev is None else prev, t0, timed,
                                 cold=not used_warm, elapsed=elapsed)
            # no answer that passes the check, or "infeasible": OSQP decides, unless the
            # time is up (the answer would come too late anyway)
            self._daqp_warm = not run.reason
            run = None if run.reason and not run.timed_out else run
        if run is None:
            q = linear_cost(self.layout, targets, self.weights.track, self.weights.terminal)
            lo, hi = fill_bounds(self._mats, self.model, th0, om0, terminal, prev)
            used_warm = warm and self._warm is not None
            start = self._warm if used_warm else None
            self._osqp.prepare(q, lo, hi,
                               None if start is None else self.layout.shift_primal(start.x, elapsed),
                               None if start is None else self.layout.shift_dual(start.y, elapsed))
            run = self._osqp.run(th0, om0, t0, timed)
        st, it, reason = run.status, run.iterations, run.reason
        if reason == "infeasible":
            self.reset()
            return refuse("infeasible", "no reference keeps the wrist inside the region under the "
                          f"speed bound from θ = {fmt_deg(th0, 3)}, θ̇ = "
                          f"{fmt_deg(om0)}/s", st, it, used_warm)
        if reason:
            self.reset()
            return refuse("failed", reason, st, it, used_warm)
        self._warm = _Warm(run.x, run.y) if run.x.size else None
        th, om, ref = run.theta_deg, run.omega_degps, run.reference_deg
        w = self.weights
        err = np.abs(th[-1] - terminal)
        cost = float((om[1:] ** 2).sum() + w.track * ((th[1:] - targets) ** 2).sum()
                     + w.terminal * err.sum())
        status: FollowStatus = "reached" if err.max() <= REACH_TOL_DEG else "tracking"
        return FollowResult(
            status=status, reference_deg=ref, position_deg=th, velocity_degps=om,
            requested_deg=requested.copy(), target_deg=terminal, clamped=clamped, clamp_deg=moved,
            cost=cost, terminal_error_deg=float(err.max()), seconds=time.perf_counter() - t0,
            iterations=it, warm=used_warm, reason="", detail=st)

    def _run_daqp(self, th0: F, om0: F, targets: F, prev: F, t0: float, timed: bool,
                  cold: bool, elapsed: int = 1) -> Solved:
        """The condensed QP by DAQP (see :mod:`~spm_console.core.planning.follow.dense`),
        within what is left of the time limit when ``timed``; checked like OSQP's answers."""
        left = None
        limit = self.settings.time_limit_s
        empty = np.zeros(0)
        if timed and limit is not None:
            left = limit - (time.perf_counter() - t0)
            if left <= 0:
                return Solved("", 0, *(empty,) * 5, out_of_time(limit, 0))
        assert self._daqp is not None
        ans = self._daqp.solve(th0, om0, targets, prev, cold=cold, time_limit_s=left,
                               elapsed=elapsed)
        if ans.flag == DAQP_TIME_LIMIT and limit is not None:
            return Solved(ans.status, ans.iterations, *(empty,) * 5,
                          out_of_time(limit, ans.iterations))
        if ans.flag != DAQP_OPTIMAL:
            return Solved(ans.status, ans.iterations, empty, empty, empty, empty, empty,
                           ans.status)
        ref = np.clip(ans.reference_deg, self._lo, self._hi)  # round-off beyond a servo limit
        th, om = self._daqp.dense.response(th0, om0, ref)
        return Solved(ans.status, ans.iterations, empty, empty, th, om, ref,
                       self._check(th, om))

    def _project_rows(self, targets: F) -> tuple[F, float]:
        """Targets projected row by row where outside; (targets, largest move in deg)."""
        inside = self._projector.admissible(targets)
        if bool(inside.all()):
            return np.array(targets, float), 0.0
        out = np.array(targets, float)
        moved = 0.0
        cache: dict[bytes, tuple[F, float]] = {}
        for k in np.flatnonzero(~inside):
            key = out[k].tobytes()
            if key not in cache:
                cache[key] = self._projector.project(out[k])
            out[k], d = cache[key]
            moved = max(moved, d)
        return out, moved

    def _outside(self, targets: F) -> bool:
        """Whether any target is outside the true region or beyond the servo limits."""
        far = float(self.region.violation_deg(targets).max()) > FOLLOW_TOL_DEG
        return bool(far or np.any(targets < self._lo - FOLLOW_TOL_DEG) or np.any(targets > self._hi + FOLLOW_TOL_DEG))

    def _check(self, th: F, om: F) -> str:
        """Empty when the predicted samples 1..H satisfy the true region and speed bound."""
        viol = float(self.region.violation_deg(th[1:]).max())
        if viol > FOLLOW_TOL_DEG:
            k = int(np.argmax(self.region.violation_deg(th[1:]))) + 1
            return f"the solution leaves the region by {viol:.3g}° at sample {k}"
        over = float(np.abs(om[1:]).max() - self.vmax_degps)
        if over > FOLLOW_TOL_DEG:
            return f"the solution exceeds the speed bound by {over:.3g}°/s"
        return ""
