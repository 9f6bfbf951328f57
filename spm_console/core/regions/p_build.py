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
(:mod:`spm_console.core.regions.refined`, used by :func:`choose_region` when the grid alone
cannot hold both configurations). The geometry is in :mod:`spm_console.core.polytope.iris`.

Angles in degrees at this interface; the solver works in scaled coordinates
x = (θ − centre) / half-range.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from spm_console.core.polytope.ellipsoid import Ellipsoid, inscribed_ellipsoid
from spm_console.core.polytope.iris import (
    Frame,
    half_widths,
    inside,
    reduce_halfspaces,
    separating_planes,
)
from spm_console.core.polytope.region import Region

if TYPE_CHECKING:
    from spm_console.core.workspace.data import Workspace

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


def iris_region(
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
    return iris_region(feasible, theta, ws.step_deg, lo, hi, home[None],
                 (np.eye(3) * ws.step_deg, home), max_halfspaces, progress)


def _home_node(ws: Workspace) -> F:
    """θ (deg) of the grid node nearest home (feasible whenever anything is)."""
    return np.asarray(ws.theta_deg()[ws.home_index])
