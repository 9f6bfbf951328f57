"""The planning problem (30): data, validation and the variable layout of the QP.

Units: θ, θ*, in degrees; θ̇ in deg/s; time in seconds. Samples k = 0..N.
Conventions (paper eq. 30): θ(0) = start, θ̇(0) = 0, θ(N) = goal, θ̇(N) = 0, the
final reference θ*(N) = goal (so the wrist stays at rest after N), and — as (30b)
is printed — θ*(0) = θ(0) (``hold_first``; set False to let the first reference move).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from fractions import Fraction

import numpy as np
from numpy.typing import NDArray

from spm_console.core.bounds import MAX_INSTANTS, N_MAX
from spm_console.core.plan_rules import BETWEEN_SPEED_ALLOWANCE, POINTS_PER_INTERVAL, SAMPLE_TOL
from spm_console.core.polytope.region import Region
from spm_console.core.regions.route import RegionRoute
from spm_console.core.servo.model import Dynamics, ServoModel, exact_step, substeps
from spm_console.errors import BadInputError, InfeasibleError, Issue
from spm_console.formatting import fmt_deg

F = NDArray[np.float64]

#: Tolerance on start/goal membership of P (deg of distance to a face).
ENDPOINT_TOL_DEG = 1e-6


@dataclass(frozen=True)
class PlanProblem:
    """One instance of (30) for three joints sharing the servo model."""

    model: ServoModel
    """Discrete servo model (28) with its p and Ts."""
    start_deg: F
    """(3,) θ(0), deg."""
    goal_deg: F
    """(3,) θ(N), deg."""
    N: int
    """Number of intervals (duration N·Ts)."""
    region: Region
    """Region P (30e), θ in degrees."""
    vmax_degps: float | None = None
    """Speed bound (30d) at the samples, deg/s; None = no bound."""
    intersample: int = 1
    """K ≥ 1: also enforce (30d, e) at the instants k·Ts + j·Ts/K, j = 1..K−1."""
    hold_first: bool = True
    """(30b) as printed: θ*(0) = θ(0)."""
    ref_lo_deg: F | None = None
    """(3,) optional lower bounds on every reference θ*(k), deg (servo limits)."""
    ref_hi_deg: F | None = None
    """(3,) optional upper bounds on every reference θ*(k), deg."""
    route: RegionRoute | None = None
    """Several regions in sequence (:mod:`spm_console.core.regions.route`) instead of
    ``region`` alone; ``region`` is then the route's first region."""
    lead_max_deg: float | None = None
    """Largest |θ*(k) − θ(k)| at the samples, deg: the servo's identified linear range (its
    drive saturates beyond, and the model no longer holds); None: unbounded, as (30)."""
    check_points: int = POINTS_PER_INTERVAL
    """Instants per interval at which the runtime checks the motion (the samples included,
    :data:`~spm_console.core.plan_rules.POINTS_PER_INTERVAL`): the plan also holds its speed
    to the runtime's between-sample bound
    v_max·(1 + :data:`~spm_console.core.plan_rules.BETWEEN_SPEED_ALLOWANCE`) there, so the
    runtime's verification accepts its speed by construction. 1: not (the problem (30) as
    printed). Only with the exact (zoh) model."""

    def __post_init__(self) -> None:
        s = np.asarray(self.start_deg, float).reshape(-1)
        g = np.asarray(self.goal_deg, float).reshape(-1)
        if s.shape != (3,) or g.shape != (3,) or not (np.all(np.isfinite(s)) and np.all(np.isfinite(g))):
            raise BadInputError("start and goal must be three finite angles in degrees")
        object.__setattr__(self, "start_deg", s)
        object.__setattr__(self, "goal_deg", g)
        if int(self.N) != self.N or not 2 <= self.N <= N_MAX:
            raise BadInputError(f"steps N must be an integer in 2..{N_MAX}, got {self.N}")
        if self.vmax_degps is not None and not (np.isfinite(self.vmax_degps) and self.vmax_degps > 0):
            raise BadInputError(f"vmax must be a positive finite speed in deg/s, got {self.vmax_degps}")
        if int(self.intersample) != self.intersample or not 1 <= self.intersample <= 100:
            raise BadInputError(f"intersample K must be an integer in 1..100, got {self.intersample}",
                                Issue.TOO_MANY_INSTANTS)
        if self.N * self.intersample > MAX_INSTANTS:
            raise BadInputError(f"N·K = {self.N} × {self.intersample} is above {MAX_INSTANTS:,} "
                                "constrained instants; use fewer steps or a smaller K", Issue.TOO_MANY_INSTANTS)
        if self.intersample > 1 and self.model.method != "zoh":
            raise BadInputError("intersample constraints need the exact (zoh) servo model",
                                Issue.TOO_MANY_INSTANTS)
        if int(self.check_points) != self.check_points or not 1 <= self.check_points <= 100:
            raise BadInputError(f"check points must be an integer in 1..100, got {self.check_points}")
        if self.route is not None and self.route.count > 1 and not self.route.fits(self.N):
            raise BadInputError(f"N = {self.N} steps leave no room for the route's switch samples "
                                f"{list(self.route.switch)}", Issue.TOO_FEW_STEPS)
        if self.lead_max_deg is not None and not (np.isfinite(self.lead_max_deg)
                                                  and self.lead_max_deg > 0):
            raise BadInputError(f"the linear range must be a positive angle in degrees, got "
                                f"{self.lead_max_deg}")
        for name in ("ref_lo_deg", "ref_hi_deg"):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, np.broadcast_to(np.asarray(v, float), (3,)).copy())

    def with_steps(self, n: int) -> PlanProblem:
        """The same problem with another horizon N."""
        route = None if self.route is None else self.route.rescaled(self.N, n)
        return replace(self, N=n, route=route)

    def with_route(self, route: RegionRoute) -> PlanProblem:
        """The same problem through another route (its first region becomes ``region``)."""
        return replace(self, region=route.regions[0], route=route)

    @property
    def regions(self) -> RegionRoute:
        """The route (one region when none was given)."""
        return self.route if self.route is not None else RegionRoute.single(self.region)

    @property
    def min_steps(self) -> int:
        """Smallest N the route leaves room for (2 for one region)."""
        return max(2, self.regions.count + 1)

    def check_endpoints(self) -> None:
        """Raise :class:`InfeasibleError` when start or goal is outside P (or refs bounds);
        along a route, the start must lie in its first region and the goal in its last."""
        route = self.regions
        for name, th, region in (("start", self.start_deg, route.regions[0]),
                                 ("goal", self.goal_deg, route.regions[-1])):
            viol = float(region.violation_deg(th))
            if viol > ENDPOINT_TOL_DEG:
                rows = np.flatnonzero(region.slack(th) / np.linalg.norm(region.A, axis=1)
                                      < -ENDPOINT_TOL_DEG)
                raise InfeasibleError(
                    f"{name} θ = {fmt_deg(th, 4)} is outside the region P by "
                    f"{viol:.4g}° (half-spaces {rows.tolist()[:8]}); choose a region that contains it")
        for name, th in (("start", self.start_deg), ("goal", self.goal_deg)):
            if self.ref_lo_deg is not None and np.any(th < self.ref_lo_deg - 1e-9):
                raise InfeasibleError(f"{name} θ = {fmt_deg(th, 4)} is below the reference limits "
                                      f"{fmt_deg(self.ref_lo_deg)}", Issue.END_NOT_FEASIBLE)
            if self.ref_hi_deg is not None and np.any(th > self.ref_hi_deg + 1e-9):
                raise InfeasibleError(f"{name} θ = {fmt_deg(th, 4)} is above the reference limits "
                                      f"{fmt_deg(self.ref_hi_deg)}", Issue.END_NOT_FEASIBLE)


@dataclass(frozen=True)
class Layout:
    """Indices of the QP variables: θ(k), θ̇(k) for k = 0..N, then θ*(k) for k = 0..N−1."""

    N: int

    @property
    def n(self) -> int:
        return 6 * (self.N + 1) + 3 * self.N

    def th(self, k: NDArray[np.int64] | int, i: NDArray[np.int64] | int) -> NDArray[np.int64]:
        return np.asarray(6 * np.asarray(k) + np.asarray(i))

    def om(self, k: NDArray[np.int64] | int, i: NDArray[np.int64] | int) -> NDArray[np.int64]:
        return np.asarray(6 * np.asarray(k) + 3 + np.asarray(i))

    def u(self, k: NDArray[np.int64] | int, i: NDArray[np.int64] | int) -> NDArray[np.int64]:
        return np.asarray(6 * (self.N + 1) + 3 * np.asarray(k) + np.asarray(i))

    def pack(self, reference_deg: F, position_deg: F, velocity_degps: F) -> F:
        """The z vector of references θ*(0..N−1) and states θ, θ̇ (N+1, 3) (the inverse of
        :meth:`unpack`, whose θ*(N) is the goal)."""
        z = np.empty(self.n)
        z[: 6 * (self.N + 1)] = np.hstack([position_deg, velocity_degps]).ravel()
        z[6 * (self.N + 1):] = np.asarray(reference_deg)[: self.N].ravel()
        return z

    def unpack(self, z: F, goal_deg: F) -> tuple[F, F, F]:
        """(reference (N+1, 3) with θ*(N) = goal, position (N+1, 3), velocity (N+1, 3))."""
        x = z[: 6 * (self.N + 1)].reshape(self.N + 1, 6)
        u = z[6 * (self.N + 1):].reshape(self.N, 3)
        ref = np.vstack([u, goal_deg[None, :]])
        return ref, x[:, :3].copy(), x[:, 3:].copy()


def sub_matrices(problem: PlanProblem) -> tuple[F, F]:
    """Exact ZOH matrices at the K−1 sub-sample instants of ``intersample`` (empty for K = 1)."""
    return substeps(problem.model.dynamics, problem.model.ts, problem.intersample)


@dataclass(frozen=True)
class SubInstants:
    """The instants inside every interval where (30d, e) are enforced besides the samples:
    the K − 1 of ``intersample`` (speed ≤ v_max and the region) and the runtime's check
    instants (speed ≤ its between-sample bound), each instant once, in time order."""

    fractions: tuple[Fraction, ...]
    """Each instant's time after the interval's sample, in periods Ts."""
    phis: F
    """(M, 2, 2) exact ZOH state matrices from the sample to each instant."""
    gams: F
    """(M, 2) … and their input columns."""
    speed_bound_degps: F
    """(M,) the speed bound at each instant, deg/s (+∞ without v_max)."""
    requested: NDArray[np.bool_]
    """(M,) whether the instant is one of ``intersample``'s (else only the runtime's: speed
    rows only)."""

    @property
    def count(self) -> int:
        return len(self.fractions)


@functools.lru_cache(maxsize=32)
def _instant_matrices(dynamics: Dynamics, ts: float, fractions: tuple[Fraction, ...]
                      ) -> tuple[F, F]:
    """(Φ (M, 2, 2), Γ (M, 2)) of :func:`exact_step` at each fraction of the period (kept
    per servo model: every plan of a session asks for the same; read-only)."""
    mats = [exact_step(dynamics, float(f) * ts) for f in fractions]
    phis = np.array([m[0] for m in mats]).reshape(len(mats), 2, 2)
    gams = np.array([m[1] for m in mats]).reshape(len(mats), 2)
    phis.flags.writeable = gams.flags.writeable = False
    return phis, gams


def sub_instants(problem: PlanProblem) -> SubInstants:
    """The :class:`SubInstants` of ``problem``: ``intersample``'s, and with the exact (zoh)
    model the runtime's ``check_points`` (those not already among them). Their speed bound
    is v_max at the former and v_max·(1 + BETWEEN_SPEED_ALLOWANCE) − SAMPLE_TOL at the latter
    (the runtime's rule 6, held with the planner's round-off to spare)."""
    v = np.inf if problem.vmax_degps is None else float(problem.vmax_degps)
    return _sub_instants(problem.model.dynamics, float(problem.model.ts),
                         problem.model.method == "zoh", int(problem.intersample),
                         int(problem.check_points), v)


@functools.lru_cache(maxsize=32)
def _sub_instants(dynamics: Dynamics, ts: float, zoh: bool, k: int, c: int,
                  v: float) -> SubInstants:
    """:func:`sub_instants` by value (kept: a route's switch search and minimum time's probes
    build many pools of one model and bound; the arrays are read-only)."""
    asked = {Fraction(j, k) for j in range(1, k)}
    runtime = {Fraction(j, c) for j in range(1, c)} - asked if zoh else set()
    fractions = tuple(sorted(asked | runtime))
    phis, gams = _instant_matrices(dynamics, ts, fractions)
    requested = np.array([f in asked for f in fractions], bool)
    between = v * (1.0 + BETWEEN_SPEED_ALLOWANCE) - SAMPLE_TOL
    speed = np.where(requested, v, between)
    requested.flags.writeable = speed.flags.writeable = False
    return SubInstants(fractions, phis, gams, speed, requested)
