"""The one way a plan is assembled, solved and checked: the console, scripts and the CLI's
``plan mvn|mintime`` all call :func:`plan_motion`.

Checks, in order: start and goal inside the servo limits (unless reference limits are off);
both feasible (:meth:`~spm_console.core.workspace.check.ThetaCheck.verdict` is the refusal's
wording); the region — given, the workspace's P, or grown around the segment
(:func:`~spm_console.core.regions.p_build.choose_region`); the solve; then the runtime's own
verification (:func:`~spm_console.motion.plan_check.verify_plan`), so only a plan that will
execute is returned; the planner meets the runtime's rules by construction, so that
verification refusing is a fault, never a reason to solve again. Degrees, deg/s, seconds.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import servo_limits_deg, servo_model_of
from spm_console.config.schema import Profile
from spm_console.core.bounds import MAX_INSTANTS, N_MAX
from spm_console.core.plan import Plan
from spm_console.core.planning.mintime import check_horizon, solve_mintime_problem
from spm_console.core.planning.mvn import solve_problem
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.planning.route_search import RouteChoice, find_route, solve_route_mvn
from spm_console.core.polytope.region import INSIDE_TOL_DEG, Region
from spm_console.core.regions.choice import RegionChoice, choose_region
from spm_console.core.regions.connect import connected_graph
from spm_console.core.workspace.build import check_theta
from spm_console.core.workspace.check import ThetaCheck
from spm_console.core.workspace.data import Workspace
from spm_console.errors import BadInputError, InfeasibleError, Issue
from spm_console.formatting import fmt_deg, fmt_vec
from spm_console.input_rules import vmax_arg
from spm_console.motion.plan_check import verify_plan
from spm_console.store.plan_file import plan_hash

F = NDArray[np.float64]

@dataclass(frozen=True)
class PlanRequest:
    """What the operator asked for."""

    method: Literal["mvn", "mintime"]
    start_deg: F
    goal_deg: F
    steps: int = 150
    """N for MVN (minimum time finds its own)."""
    vmax_degps: float | None = None
    """Speed bound at the samples; None: the profile's ``limits.vmax_degps``."""
    intersample: int = 1
    """K ≥ 1: also bound speed and region at K−1 instants inside each interval."""
    hold_first: bool = True
    """θ*(0) = θ(0), (30b) as printed; False lets the first reference move."""
    reference_limits: bool = True
    """Keep every reference inside the servo limits."""
    region: Region | None = None
    """A region given by the operator (e.g. a file); None: P, or grown around the segment."""
    region_source: str = ""


@dataclass(frozen=True)
class PlannedMotion:
    """A verified plan and what it was planned in."""

    plan: Plan
    region: RegionChoice | None
    """The one region the plan lies in (None for a plan across several regions)."""
    start: ThetaCheck
    goal: ThetaCheck
    route: RouteChoice | None = None
    """The sequence of the workspace's cover regions a plan across regions went through."""

    @property
    def region_kind(self) -> str:
        """"P", "grown", "given" (one region, see :class:`RegionChoice`), "cover" (one region
        of the workspace's cover) or "route" (several)."""
        if self.region is not None:
            return self.region.kind
        return "route" if self.plan.regions.count > 1 else "cover"

    def describe_region(self) -> str:
        """One line naming the region(s) the plan used and their size."""
        if self.region is not None:
            return self.region.describe()
        route = self.plan.regions
        sizes = ", ".join(f"{r.halfspaces}" for r in route.regions)
        if route.count == 1:
            name = self.route.regions[0] if self.route is not None else "?"
            return f"region {name} of the workspace's region cover ({sizes} half-spaces)"
        return (f"a route through the workspace's region cover: {route.describe()} "
                f"({sizes} half-spaces)")


def precheck(profile: Profile, req: PlanRequest) -> None:
    """What can be refused without the workspace (milliseconds): a speed bound above the
    profile's planning limit (the runtime refuses such a plan), the servo limits, and for
    minimum time a speed bound too low for any horizon the planner may try."""
    vmax_arg(req.vmax_degps, profile, what="the speed bound")
    s = np.asarray(req.start_deg, float).reshape(3)
    g = np.asarray(req.goal_deg, float).reshape(3)
    lo, hi = servo_limits_deg(profile)
    if req.reference_limits:
        for name, th in (("start", s), ("goal", g)):
            if np.any(th < lo) or np.any(th > hi):
                raise BadInputError(
                    f"{name} θ = {fmt_deg(th)} is outside the servo limits "
                    f"{fmt_vec(lo, 2)}…{fmt_deg(hi)}", Issue.END_NOT_FEASIBLE)
    if req.method == "mintime":
        vmax = profile.limits.vmax_degps if req.vmax_degps is None else float(req.vmax_degps)
        check_horizon(servo_model_of(profile), s, g, vmax,
                      min(N_MAX, MAX_INSTANTS // max(1, int(req.intersample))))


def plan_motion(profile: Profile, ws: Workspace, req: PlanRequest) -> PlannedMotion:
    """Assemble, solve and verify (see the module docstring); raises the SpmError that says
    why not (bad input 4, infeasible 6, plan refused 26), with the Issue it was raised with.

    The planner holds the motion to the runtime's rules where the runtime checks them
    (:attr:`~spm_console.core.planning.problem.PlanProblem.check_points`), and its report's
    verdict is those rules', so the runtime's verification accepts what it returns; the
    verification runs all the same (against the workspace's certified set), and a refusal
    there is raised as it is, never worked around by solving again."""
    precheck(profile, req)
    s = np.asarray(req.start_deg, float).reshape(3)
    g = np.asarray(req.goal_deg, float).reshape(3)
    lo, hi = servo_limits_deg(profile)
    checks = []
    for name, th in (("start", s), ("goal", g)):
        chk = check_theta(ws, th)
        if not chk.feasible:
            raise InfeasibleError(f"{name} θ = {fmt_deg(th)} is {chk.verdict}",
                                  Issue.END_NOT_FEASIBLE)
        checks.append(chk)
    vmax = profile.limits.vmax_degps if req.vmax_degps is None else float(req.vmax_degps)
    pb = PlanProblem(servo_model_of(profile), s, g, int(req.steps), ws.region, vmax,
                     int(req.intersample), req.hold_first,
                     lo if req.reference_limits else None, hi if req.reference_limits else None,
                     lead_max_deg=profile.servo.linear_range_deg)
    in_p = bool(ws.region.contains(np.stack([s, g]), tol=INSIDE_TOL_DEG).all())  # as choose_region
    route_error: InfeasibleError | None = None
    if req.region is None and not in_p:
        try:
            routed = _plan_along_cover(profile, ws, pb, req)
        except InfeasibleError as exc:
            routed, route_error = None, exc
        if routed is not None:
            verify_plan(profile, ws, routed[0])  # the executor's own check, as below
            return PlannedMotion(routed[0], None, checks[0], checks[1], routed[1])
    try:
        if req.region is not None:
            choice = RegionChoice(req.region, "given", req.region_source)
        else:  # P holds both ends (tested above), else a region grown for the segment
            choice = RegionChoice(ws.region, "P") if in_p else choose_region(ws, s, g)
    except InfeasibleError as exc:
        if route_error is not None:  # the route's issue, more specific when it has one
            raise InfeasibleError(f"{exc}; along the workspace's region cover: {route_error}",
                                  route_error.issue or exc.issue) from exc
        raise
    pb = replace(pb, region=tube(profile, choice.region, s, g))
    if req.method == "mvn":
        plan = solve_problem(pb).to_plan("mvn", plan_hash(profile))
    else:
        plan = solve_mintime_problem(pb).to_plan("mintime", plan_hash(profile))
    verify_plan(profile, ws, plan)  # exactly the executor's check: emit only what executes
    return PlannedMotion(plan, choice, checks[0], checks[1])


def tube(profile: Profile, region: Region, start_deg: F, goal_deg: F) -> Region:
    """``region`` tightened by the servo's residual bound (the largest model error seen on
    held-out data), so the measured motion, off the model by at most that, stays inside it;
    faces nearer the start or goal than the bound move only as far as those (a plan must
    start and end there). The region itself for a profile without a residual bound."""
    r = profile.servo.residual_bound_deg
    if r is None:
        return region
    return region.tightened(r, np.stack([start_deg, goal_deg]))


def _plan_along_cover(profile: Profile, ws: Workspace, pb: PlanProblem,
                      req: PlanRequest) -> tuple[Plan, RouteChoice] | None:
    """A plan through the workspace's cover regions (None without a cover, or when the
    route is a single region that a grown region does as well); InfeasibleError says why
    no route joins start and goal or its plan failed."""
    cover = ws.cover
    if cover is None:
        return None
    # an end on the boundary of the certified set may lie in no cover region: a small
    # region grown around it (same obstacles, certified alike) connects it to the cover
    graph = connected_graph(ws, cover, np.stack([pb.start_deg, pb.goal_deg]))
    regions = graph.regions
    labels = (["P"] + [f"cover region {i}" for i in range(1, len(cover.regions))]
              + [f"region grown around an end ({i + 1})" for i in range(graph.grown)])
    choice = find_route(regions, graph.points_deg, pb.start_deg, pb.goal_deg)
    if choice is None:
        raise InfeasibleError("no sequence of overlapping certified regions joins start and goal")
    if req.method == "mvn":
        res = solve_route_mvn(pb, regions, choice, labels).result
        return res.to_plan("mvn", plan_hash(profile)), choice
    steps = max(pb.N, len(choice.regions) + 1)
    route = choice.route(regions, steps, labels)
    mt = solve_mintime_problem(pb.with_steps(steps).with_route(route))
    return mt.to_plan("mintime", plan_hash(profile)), choice
