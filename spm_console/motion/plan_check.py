"""The runtime's own verification of every plan before torque-on.

Nothing a plan file (or any front end) claims is believed: its region, model, positions
and velocities are ignored. From the references alone and **this profile's** servo model
(27) and workspace, the motion is simulated exactly (zero-order hold) at every sample and
at :data:`POINTS_PER_INTERVAL` instants in every interval, plus a settling tail holding the
last reference, and refused (:class:`PlanRefusedError`, exit 26) unless

* the references are finite, sampled at the profile's Ts, no longer than :data:`MAX_SAMPLES`;
* every reference and every simulated position lies inside the servo limits (1e-9° of
  tolerance on the boundary);
* no reference changes by more than :data:`MAX_REFERENCE_STEP_DEG` between samples;
* the model speed stays within the profile's ``limits.vmax_degps`` at the samples, and
  within it plus :data:`BETWEEN_SPEED_ALLOWANCE` between samples (piecewise-constant
  references make the continuous speed overshoot the sampled one: 5 % for the paper's
  minimum-time plan; plans solved with ``--intersample`` meet the bound exactly);
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

from spm_console.config.models import link_model_of, model_of, servo_limits_deg
from spm_console.config.schema import Profile
from spm_console.core.plan import Plan
from spm_console.core.servo.model import simulate_continuous
from spm_console.core.workspace.certify import CertifiedSet
from spm_console.core.workspace.check import check_points
from spm_console.core.workspace.data import Workspace
from spm_console.core.workspace.refine import RefinedCertifiedSet
from spm_console.errors import PlanRefusedError
from spm_console.motion.plans import settle_samples
from spm_console.motion.segments import Segment

F = NDArray[np.float64]

#: Instants simulated per sampling interval (the samples included).
POINTS_PER_INTERVAL = 10
#: Largest change of a reference between two samples, deg (a 10° step is 500°/s of command).
MAX_REFERENCE_STEP_DEG = 10.0
#: Relative allowance on the speed bound between samples (not at the samples).
BETWEEN_SPEED_ALLOWANCE = 0.10
#: Tolerance on the servo-limit boundary, deg.
LIMIT_TOL_DEG = 1e-9
#: Tolerance on the speed bound at the samples, deg/s (solver round-off).
SPEED_TOL_DEGPS = 1e-6
#: Longest plan accepted, samples (10 minutes at 20 ms).
MAX_SAMPLES = 30_000
#: Phases built by the runtime as straight lines from a measured position.
LINE_PHASES = ("homing", "approach")


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
    def _refuse(self, seg: Segment, what: str) -> PlanRefusedError:
        return PlanRefusedError(f"{seg.phase} refused by the runtime's plan verification: {what}")

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
        self._limits(seg, ref, "reference θ*")
        steps = np.abs(np.diff(ref, axis=0))
        step = float(steps.max()) if steps.size else 0.0
        if step > MAX_REFERENCE_STEP_DEG:
            k, i = (int(x) for x in np.unravel_index(int(np.argmax(steps)), steps.shape))
            raise self._refuse(seg, f"reference θ{i + 1} jumps {steps[k, i]:.2f}° between samples "
                                    f"{k} and {k + 1} (at most {MAX_REFERENCE_STEP_DEG:g}° per sample)")
        tail = np.repeat(ref[-1:], settle_samples(self.profile), axis=0)
        full = np.concatenate([ref, tail])
        x0 = np.column_stack([ref[0], np.zeros(3)])
        _, xs = simulate_continuous(self.profile.servo.p, ts, x0, full, POINTS_PER_INTERVAL)
        pos, vel = xs[..., 0], xs[..., 1]
        self._limits(seg, pos, "the model position θ")
        self._speed(seg, vel)
        if seg.phase in LINE_PHASES:
            self._exact(seg, pos)
        else:
            self._certified(seg, pos)
        return len(pos), float(np.abs(vel).max()), step

    def _limits(self, seg: Segment, th: F, what: str) -> None:
        bad = (th < self.lo - LIMIT_TOL_DEG) | (th > self.hi + LIMIT_TOL_DEG)
        if bad.any():
            k, i = (int(x) for x in np.argwhere(bad)[0])
            raise self._refuse(seg, f"{what}{i + 1} = {th[k, i]:.6g}° at point {k} is outside the "
                                    f"servo limits [{self.lo[i]:g}, {self.hi[i]:g}]°")

    def _speed(self, seg: Segment, vel: F) -> None:
        at_samples = np.abs(vel[::POINTS_PER_INTERVAL])
        between = np.abs(vel)
        cap = self.vmax * (1.0 + BETWEEN_SPEED_ALLOWANCE)
        if float(at_samples.max()) > self.vmax + SPEED_TOL_DEGPS:
            k, i = (int(x) for x in np.unravel_index(int(np.argmax(at_samples)), at_samples.shape))
            raise self._refuse(seg, f"the model speed of joint {i + 1} reaches {at_samples[k, i]:.1f}°/s "
                                    f"at sample {k}, above the profile's limits.vmax_degps = {self.vmax:g}°/s")
        if float(between.max()) > cap:
            m, i = (int(x) for x in np.unravel_index(int(np.argmax(between)), between.shape))
            raise self._refuse(seg, f"between samples {m // POINTS_PER_INTERVAL} and "
                                    f"{m // POINTS_PER_INTERVAL + 1} the model speed of joint {i + 1} "
                                    f"reaches {between[m, i]:.1f}°/s, above {cap:.1f}°/s "
                                    f"(limits.vmax_degps + {BETWEEN_SPEED_ALLOWANCE:.0%})")

    def _certified(self, seg: Segment, pos: F) -> None:
        if self.certified.empty:
            raise self._refuse(seg, "the workspace of this profile has no feasible node, so it "
                                    "certifies no motion (check the profile's links, δ and ζ_min)")
        ok = self.certified.contains(pos)
        if not ok.all():
            m = int(np.argmin(ok))
            raise self._refuse(seg, f"the motion reaches θ = {_fmt(pos[m])}° (between samples "
                                    f"{m // POINTS_PER_INTERVAL} and {m // POINTS_PER_INTERVAL + 1}), "
                                    "which this profile's workspace does not certify feasible "
                                    f"(within Δ = {self.certified.step_deg:g}° of an infeasible grid "
                                    f"node{self._fine_note()} or outside the grid); whatever region "
                                    "the plan names")

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
