"""The runtime's own verification of every plan before torque-on.

Nothing a plan file (or any front end) claims is believed: its region, model, positions
and velocities are ignored. From the references alone and **this profile's** servo model
(27) and workspace, the motion is simulated exactly (zero-order hold) at every sample and
at :data:`~spm_console.core.plan_rules.POINTS_PER_INTERVAL` instants in every interval, plus
a settling tail holding the last reference, and refused (:class:`PlanRefusedError`, exit 26)
unless it meets the runtime's rules (:func:`spm_console.core.plan_rules.check_motion`, the
same the live follower applies to each re-planned horizon; worded here):

* the references are finite, sampled at the profile's Ts, no longer than
  :data:`~spm_console.core.plan_rules.MAX_SAMPLES`;
* every reference and every simulated position lies inside the servo limits (1e-9° of
  tolerance on the boundary);
* no reference changes by more than
  :data:`~spm_console.core.plan_rules.MAX_REFERENCE_STEP_DEG` between samples;
* the model speed stays within the profile's ``limits.vmax_degps`` at the samples, and
  within it plus :data:`~spm_console.core.plan_rules.BETWEEN_SPEED_ALLOWANCE` between
  samples (piecewise-constant references make the continuous speed overshoot the sampled
  one: 5 % for the paper's minimum-time plan; plans solved with ``--intersample`` meet the
  bound exactly);
* every simulated position of a planned segment is certified by the workspace: by the grid
  (:class:`~spm_console.core.workspace.certify.CertifiedSet`, the grid's P′) or, near the boundary, by
  the same criterion at the fine resolution Δ/4
  (:class:`~spm_console.core.workspace.refine.RefinedCertifiedSet`, fine nodes checked exactly by the
  runtime itself from this profile's workspace, never taken from the plan): a workspace with
  no feasible node certifies nothing, so nothing can be executed in it;
* a straight homing/approach move (built by the runtime from a measured position, which
  may lie between grid nodes or outside the grid) passes the exact checks along its
  continuous motion instead: FK tracked in the home assembly mode, ζ ≥ ζ_min and links at
  least 2δ apart.

Degrees, deg/s, seconds.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import link_model_of, model_of, servo_limits_deg, servo_model_of
from spm_console.config.schema import Profile
from spm_console.core.plan import Plan
from spm_console.core.plan_rules import (
    BETWEEN_SPEED_ALLOWANCE,
    MAX_REFERENCE_STEP_DEG,
    MAX_SAMPLES,
    POINTS_PER_INTERVAL,
    Rule,
    Violation,
    check_motion,
)
from spm_console.core.workspace.certify import CertifiedSet
from spm_console.core.workspace.check import check_points
from spm_console.core.workspace.data import Workspace
from spm_console.core.workspace.refine import RefinedCertifiedSet
from spm_console.errors import Issue, PlanRefusedError
from spm_console.motion.plans import settle_samples
from spm_console.motion.segments import Segment

F = NDArray[np.float64]

#: Phases built by the runtime as straight lines from a measured position.
LINE_PHASES = ("homing", "approach")

#: What went wrong, for a front end's advice, when a motion breaks a rule: beyond the servo
#: limits, the start or goal lies too near them.
_ISSUES: dict[Rule, Issue] = {Rule.REFERENCE_LIMIT: Issue.END_NOT_FEASIBLE,
                              Rule.POSITION_LIMIT: Issue.END_NOT_FEASIBLE}

LEAD_KINDS = frozenset({"mvn", "mintime"})
"""Plans held to the servo's linear range: the planner's, which choose how far the reference
runs ahead. Lines (homing, approach, jog) are slow by construction, and the identification
experiment probes beyond the range on purpose."""


@dataclass(frozen=True)
class PlanCheck:
    """What the verification looked at (logged with every run)."""

    segments: int
    points: int
    """Simulated instants checked (samples, between samples and the settling tail)."""
    max_speed_degps: float
    """Largest model speed between samples, deg/s."""
    max_reference_step_deg: float
    seconds: float


def _fmt(v: F) -> str:
    return "[" + ", ".join(f"{x:.2f}" for x in v) + "]"


class PlanVerifier:
    """Verifies segments against one profile and its workspace (see module docstring)."""

    def __init__(self, profile: Profile, workspace: Workspace) -> None:
        self.profile = profile
        self.ws = workspace
        self.certified: CertifiedSet = (RefinedCertifiedSet.of(workspace)
                                        if workspace.model is not None and workspace.links is not None
                                        else workspace.certified_set())
        """The grid's certified set, refined near the boundary when the workspace carries its
        models (fine verdicts memoized: the executor's safety monitor shares them)."""
        self.lo, self.hi = servo_limits_deg(profile)
        self.vmax = profile.limits.vmax_degps

    def verify(self, segments: Sequence[Segment]) -> PlanCheck:
        """Raise :class:`PlanRefusedError` naming the first violation; else what was checked."""
        t0 = time.perf_counter()
        if not segments:
            raise PlanRefusedError("nothing to execute: no plan segments")
        points, vmax_seen, step_seen = 0, 0.0, 0.0
        for seg in segments:
            pts, v, step = self._segment(seg)
            points, vmax_seen, step_seen = points + pts, max(vmax_seen, v), max(step_seen, step)
        return PlanCheck(len(segments), points, vmax_seen, step_seen, time.perf_counter() - t0)

    # ------------------------------------------------------------------ one segment
    def _refuse(self, seg: Segment, what: str, issue: Issue | None = None) -> PlanRefusedError:
        return PlanRefusedError(f"{seg.phase} refused by the runtime's plan verification: {what}",
                                issue)

    def _segment(self, seg: Segment) -> tuple[int, float, float]:
        plan, ts = seg.plan, self.profile.servo.ts_s
        ref = np.asarray(plan.reference_deg, float)
        if ref.ndim != 2 or ref.shape[1] != 3 or len(ref) < 1:
            raise self._refuse(seg, f"references must be an (N+1, 3) array, got shape {ref.shape}")
        if len(ref) > MAX_SAMPLES:
            raise self._refuse(seg, f"{len(ref)} samples, more than {MAX_SAMPLES}")
        if not np.all(np.isfinite(ref)):
            raise self._refuse(seg, "references must be finite angles")
        if not math.isfinite(plan.Ts) or abs(plan.Ts - ts) > 1e-9:
            raise self._refuse(seg, f"sampled at Ts = {plan.Ts} s but the servos run at Ts = {ts} s")
        line = seg.phase in LINE_PHASES
        x0 = np.column_stack([ref[0], np.zeros(3)])
        optimal = plan.kind in LEAD_KINDS
        check = check_motion(servo_model_of(self.profile).dynamics, ts, x0, ref, self.lo,
                             self.hi, self.vmax, None if line else self.certified,
                             hold_samples=settle_samples(self.profile),
                             lead_max_deg=self.profile.servo.linear_range_deg if optimal else None)
        if check.violation is not None:
            raise self._refuse(seg, self._words(check.violation, check.positions_deg),
                               _ISSUES.get(check.violation.rule))
        if line:
            self._exact(seg, check.positions_deg)
        return check.points, check.max_speed_degps, check.max_step_deg

    def _words(self, v: Violation, pos: F) -> str:
        """What the operator reads about a violation of the runtime's rules."""
        k, i = v.index, v.joint
        between = f"{k // POINTS_PER_INTERVAL} and {k // POINTS_PER_INTERVAL + 1}"
        if v.rule in (Rule.REFERENCE_LIMIT, Rule.POSITION_LIMIT):
            what = "reference θ*" if v.rule is Rule.REFERENCE_LIMIT else "the model position θ"
            return (f"{what}{i + 1} = {v.value:.6g}° at point {k} is outside the "
                    f"servo limits [{self.lo[i]:g}, {self.hi[i]:g}]°")
        if v.rule is Rule.STEP:
            return (f"reference θ{i + 1} jumps {v.value:.2f}° between samples "
                    f"{k} and {k + 1} (at most {MAX_REFERENCE_STEP_DEG:g}° per sample)")
        if v.rule is Rule.SPEED_AT_SAMPLE:
            return (f"the model speed of joint {i + 1} reaches {v.value:.1f}°/s "
                    f"at sample {k}, above the profile's limits.vmax_degps = {self.vmax:g}°/s")
        if v.rule is Rule.SPEED_BETWEEN:
            return (f"between samples {between} the model speed of joint {i + 1} "
                    f"reaches {v.value:.1f}°/s, above {v.bound:.1f}°/s "
                    f"(limits.vmax_degps + {BETWEEN_SPEED_ALLOWANCE:.0%})")
        if v.rule is Rule.LEAD:
            return (f"reference θ{i + 1} runs {v.value:.2f}° ahead of the model position at "
                    f"sample {k}, beyond the servo's linear range servo.linear_range_deg = "
                    f"{v.bound:g}° (its drive saturates there and the model no longer holds)")
        if v.rule is Rule.NOTHING_CERTIFIED:
            return ("the workspace of this profile has no feasible node, so it "
                    "certifies no motion (check the profile's links, δ and ζ_min)")
        if v.rule is Rule.NOT_CERTIFIED:
            return (f"the motion reaches θ = {_fmt(pos[k])}° (between samples {between}), "
                    "which this profile's workspace does not certify feasible "
                    f"(within Δ = {self.certified.step_deg:g}° of an infeasible grid "
                    f"node{self._fine_note()} or outside the grid); whatever region "
                    "the plan names")
        return "references must be finite angles"  # Rule.NOT_FINITE

    def _fine_note(self) -> str:
        c = self.certified
        if isinstance(c, RefinedCertifiedSet) and c.fine is not None:
            return f" and within h = {c.resolution_deg:g}° of a fine node that fails the exact checks"
        return ""

    def _exact(self, seg: Segment, pos: F) -> None:
        ws, prof = self.ws, self.profile
        # the exact checks every Δ/4 of motion (as the segment check does), and the end
        moved = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(pos, axis=0)).max(axis=1))])
        first = np.unique(np.floor(moved / (0.25 * ws.step_deg)), return_index=True)[1]
        pts = pos[np.union1d(first, [len(pos) - 1])]
        links = link_model_of(prof)
        pc = check_points(ws, model_of(prof), links, pts)
        with np.errstate(invalid="ignore"):  # outside the grid is fine here: exact checks only
            ok = pc.fk_ok & (pc.zeta >= ws.zeta_min) & (pc.min_link_mm >= ws.min_distance_mm)
        if not ok.all():
            k = int(np.argmin(ok))
            why = pc.reason(k, ws.zeta_min, ws.min_distance_mm, links)
            raise self._refuse(seg, f"the straight move passes θ = {_fmt(pts[k])}°: {why}. Bring the "
                                    "wrist nearer home by hand (torque off) and home again")


def verify_plan(profile: Profile, workspace: Workspace, plan: Plan) -> PlanCheck:
    """Verify one planned segment exactly as the executor will before torque-on: a planner
    emits only plans the runtime accepts (:class:`PlanRefusedError` otherwise)."""
    return PlanVerifier(profile, workspace).verify([Segment("plan", plan)])
