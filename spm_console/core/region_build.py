"""The convex region P ⊆ P' (paper eq. 26), built IRIS-style from the classified grid.

P' = (∪_{θ∈V} θ ⊕ C_Δ) ⊖ C_Δ is, on the grid, the set of points at L∞ distance
≥ Δ from every node that is not home-connected feasible, and inside the grid box:
the union of the grid cells whose 8 corners are all feasible. So P must avoid the
*open cube of half-width Δ* around every infeasible node. Only infeasible nodes
with a feasible 26-neighbour can be touched first by a convex set grown inside the
feasible set, so those are the obstacles; the grid box adds six half-spaces.

IRIS (Deits & Tedrake 2015) alternates two steps:
1. separating planes: in the metric of the current ellipsoid E, take the closest
   remaining obstacle cube, add the plane tangent to E's level set at its closest
   point (the whole cube lies beyond it), drop every cube beyond it, repeat;
2. the maximum-volume ellipsoid inscribed in the resulting polytope.
Required points (home, or the two configurations of :func:`region_containing`)
are never cut: a plane that would cut one is replaced by the max-margin plane
between the required points and that cube (an LP).

Near the boundary a region may instead avoid a mixed set of cubes: half-width Δ around
grid nodes, and half-width h = Δ/4 around the infeasible fine nodes of refined grid nodes
(:mod:`spm_console.core.region_refine`, used by :func:`choose_region` when the grid alone
cannot hold both configurations). The geometry is in :mod:`spm_console.core.iris`.

Angles in degrees at this interface; the solver works in scaled coordinates
x = (θ − centre) / half-range.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.core.ellipsoid import Ellipsoid, inscribed_ellipsoid
from spm_console.core.iris import INSIDE_TOL_DEG as INSIDE_TOL_DEG
from spm_console.core.iris import Frame, half_widths, inside
from spm_console.core.iris import closest_on_boxes as closest_on_boxes
from spm_console.core.iris import reduce_halfspaces as reduce_halfspaces
from spm_console.core.iris import separating_planes as separating_planes
from spm_console.core.region import Region
from spm_console.errors import InfeasibleError

if TYPE_CHECKING:
    from spm_console.core.refine import FineGrid
    from spm_console.core.workspace import Workspace

F = NDArray[np.float64]
B = NDArray[np.bool_]

#: IRIS stops when the ellipsoid volume grows by less than this fraction.
VOLUME_TOL = 0.02
#: Maximum IRIS iterations.
MAX_ITERS = 6
#: Feasible nodes used as the objective of the heuristics (random subset beyond this).
OBJECTIVE_POINTS = 20_000
#: Feasible nodes per piece of P's final coverage count (bounds the gap between reports).
COVERAGE_CHUNK = 50_000


@dataclass(frozen=True)
class RegionBuild:
    """Result of a region construction (object, not tuple)."""

    region: Region
    """P with unit-norm rows, θ in degrees."""
    coverage: float
    """Fraction of feasible nodes inside P."""
    iterations: int
    """IRIS iterations run."""
    obstacles: int
    """Obstacle cubes considered (infeasible nodes next to feasible ones)."""
    log_volume: float
    """log det of the last inscribed ellipsoid (scaled coordinates)."""
    seconds: float
    iris_planes: int = 0
    """Non-redundant planes IRIS produced before any reduction to the cap."""

    def info(self) -> dict[str, float]:
        return {
            "iris_planes": float(self.iris_planes),
            "coverage": self.coverage, "iterations": float(self.iterations),
            "obstacles": float(self.obstacles), "halfspaces": float(self.region.halfspaces),
            "log_volume": self.log_volume, "seconds": self.seconds,
        }


def obstacle_nodes(feasible: B, theta_deg: F) -> F:
    """θ (deg) of the infeasible nodes that have a feasible 26-neighbour: (n, 3)."""
    from scipy import ndimage  # here: only a build needs it (~0.4 s to import)

    near = ndimage.binary_dilation(feasible, structure=np.ones((3, 3, 3), bool))
    return np.asarray(theta_deg[near & ~feasible])


def _iris(
    feasible: B, theta_deg: F, step_deg: float, lo: float, hi: float, req_deg: F,
    E0_deg: tuple[F, F], max_halfspaces: int,
    progress: Callable[[float], None] | None = None,
    *, obstacles: tuple[F, F] | None = None,
) -> RegionBuild:
    """IRIS inside the grid box [lo, hi]³ keeping ``req_deg``. Obstacles: the open cubes of
    half-width Δ around :func:`obstacle_nodes`, or ``obstacles`` = (centres (n, 3) deg,
    half-widths (n,) or one value, deg) when given."""
    t0 = time.perf_counter()
    frame = Frame(np.full(3, 0.5 * (lo + hi)), 0.5 * (hi - lo))
    if obstacles is None:
        Q = frame.to_x(obstacle_nodes(feasible, theta_deg))
        half: float | F = step_deg / frame.s
    else:
        Q = frame.to_x(np.asarray(obstacles[0], float).reshape(-1, 3))
        half = half_widths(obstacles[1], len(Q)) / frame.s
    req = frame.to_x(req_deg).reshape(-1, 3)
    Abox = np.vstack([np.eye(3), -np.eye(3)])
    bbox = np.ones(6)
    E = Ellipsoid(E0_deg[0] / frame.s, frame.to_x(E0_deg[1]))
    feas_pts = theta_deg[feasible]
    # objective points of the heuristics: a fixed random subset (exact coverage at the end)
    rng = np.random.default_rng(0)
    obj = feas_pts if len(feas_pts) <= OBJECTIVE_POINTS else feas_pts[
        rng.choice(len(feas_pts), OBJECTIVE_POINTS, replace=False)]
    best: RegionBuild | None = None
    it = 0
    for it in range(1, MAX_ITERS + 1):
        Ap, bp = separating_planes(E, Q, half, req)
        cand = frame.region(np.vstack([Abox, Ap]), np.r_[bbox, bp]).without_redundant()
        raw_planes = cand.halfspaces
        cov = float(inside(cand, obj).mean()) if len(obj) else 0.0
        # next ellipsoid inside the candidate, in scaled coordinates
        Ax = cand.A * frame.s
        bx = cand.b - cand.A @ frame.c
        E_new = inscribed_ellipsoid(Ax, bx)
        grow = E_new.log_volume - E.log_volume
        if best is None or cov > best.coverage:
            best = RegionBuild(cand, cov, it, len(Q), E_new.log_volume, 0.0, raw_planes)
        if progress is not None:
            progress(it / MAX_ITERS)
        E = E_new
        if it > 1 and grow < np.log1p(VOLUME_TOL):
            break
    assert best is not None
    final = reduce_halfspaces(best.region, frame, Q, half, req, max_halfspaces, obj,
                              tick=None if progress is None else lambda: progress(it / MAX_ITERS))
    n_in = 0
    for c in range(0, len(feas_pts), COVERAGE_CHUNK):  # in pieces: ~1.3 s on the 1° grid
        n_in += int(inside(final, feas_pts[c:c + COVERAGE_CHUNK]).sum())
        if progress is not None:
            progress(it / MAX_ITERS)
    cov = n_in / len(feas_pts) if len(feas_pts) else 0.0
    return RegionBuild(final, cov, it, best.obstacles, best.log_volume,
                       time.perf_counter() - t0, best.iris_planes)


def build_region(
    ws: Workspace, max_halfspaces: int = 64, progress: Callable[[float], None] | None = None
) -> RegionBuild:
    """The default P of a workspace: IRIS grown from the home node (which it contains)."""
    feasible = ws.feasible
    lo, hi = ws.range_deg()
    theta = ws.theta_deg()
    home = _home_node(ws)
    return _iris(feasible, theta, ws.step_deg, lo, hi, home[None],
                 (np.eye(3) * ws.step_deg, home), max_halfspaces, progress)


def _home_node(ws: Workspace) -> F:
    """θ (deg) of the grid node nearest home (feasible whenever anything is)."""
    return np.asarray(ws.theta_deg()[ws.home_index])


@dataclass(frozen=True)
class RegionChoice:
    """The region a plan between two configurations uses, and where it came from."""

    region: Region
    kind: Literal["P", "grown", "refined", "given"]
    """The workspace's cached P, a region grown around the straight segment on the grid, one
    grown around it with the grid refined near the boundary (``resolution_deg``), or one
    given by the operator (``source`` says which)."""
    source: str = ""
    resolution_deg: float | None = None
    """The fine resolution h of a refined region, deg."""

    def describe(self) -> str:
        """One line naming the region and its size (half-spaces, inscribed ball radius)."""
        _, radius = self.region.chebyshev()
        h = self.resolution_deg
        refined = ("a region grown around the segment, certified at the refined resolution "
                   f"h = {h:g}° near the boundary" if h is not None
                   else "a region grown around the segment, refined near the boundary")
        what = {"P": "the workspace region P", "grown": "a region grown around the segment",
                "refined": refined, "given": self.source or "the given region"}[self.kind]
        return (f"{what} ({self.region.halfspaces} half-spaces, inscribed ball radius "
                f"{radius:.1f}°)")


def choose_region(ws: Workspace, theta_a_deg: F, theta_b_deg: F,
                  fine: FineGrid | None = None) -> RegionChoice:
    """A region (θ in degrees) containing both configurations: the cached P if it already
    does, else an IRIS region grown around the straight segment between them on the grid,
    else (the segment passes within Δ of an infeasible grid node, or the grid region cannot
    hold both) one grown with the grid refined near the segment
    (:func:`~spm_console.core.region_refine.refined_region`; ``fine`` memoizes its exact
    checks across calls). Raises :class:`InfeasibleError` naming why when the segment
    leaves the feasible set."""
    from spm_console.core.region_refine import refined_region
    from spm_console.core.segment_check import check_range, check_segment, exact_samples

    a = np.asarray(theta_a_deg, float)
    b = np.asarray(theta_b_deg, float)
    if not bool(ws.feasible.any()):
        raise InfeasibleError("the workspace has no feasible node (every grid node is singular, "
                              "colliding or unreachable): nothing can be planned in it; check the "
                              "profile's links, δ and ζ_min")
    if bool(ws.region.contains(np.stack([a, b]), tol=1e-9).all()):
        return RegionChoice(ws.region, "P")
    check_range(ws, a, b)
    ex = exact_samples(ws, a, b)
    try:
        check_segment(ws, a, b, samples=ex)
    except InfeasibleError:
        if not ex.feasible:
            raise  # infeasible at an exact sample: refining cannot help
    else:
        lo, hi = ws.range_deg()
        # seed: the inscribed ellipsoid of the default P (planes that would cut a or b
        # are turned just enough to keep them)
        E = inscribed_ellipsoid(ws.region.A, ws.region.b)
        limit = max(ws.region.halfspaces, int(ws.region_info.get("max_halfspaces", 64)))
        res = _iris(ws.feasible, ws.theta_deg(), ws.step_deg, lo, hi, np.stack([a, b]),
                    (E.C, E.d), limit)
        if bool(res.region.contains(np.stack([a, b]), tol=1e-7).all()):
            return RegionChoice(res.region, "grown")
    rr = refined_region(ws, a, b, fine, samples=ex)
    return RegionChoice(rr.region, "refined", resolution_deg=rr.refinement.h_deg)


def region_containing(ws: Workspace, theta_a_deg: F, theta_b_deg: F) -> Region:
    """The region of :func:`choose_region`."""
    return choose_region(ws, theta_a_deg, theta_b_deg).region
