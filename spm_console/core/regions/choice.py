"""The region a plan between two configurations uses: the workspace's P when it holds both
ends, else a region grown around the segment on the grid, else one grown with the grid
refined near the segment (θ in degrees)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.core.polytope.ellipsoid import inscribed_ellipsoid
from spm_console.core.polytope.region import INSIDE_TOL_DEG, Region
from spm_console.core.regions.p_build import iris_region
from spm_console.core.regions.refined import refined_region
from spm_console.core.workspace.data import Workspace
from spm_console.core.workspace.refine import FineGrid
from spm_console.core.workspace.segment_check import check_range, check_segment, exact_samples
from spm_console.errors import InfeasibleError, Issue

F = NDArray[np.float64]


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
    (:func:`~spm_console.core.regions.refined.refined_region`; ``fine`` memoizes its exact
    checks across calls). Raises :class:`InfeasibleError` naming why when the segment
    leaves the feasible set."""
    a = np.asarray(theta_a_deg, float)
    b = np.asarray(theta_b_deg, float)
    if not bool(ws.feasible.any()):
        raise InfeasibleError("the workspace has no feasible node (every grid node is singular, "
                              "colliding or unreachable): nothing can be planned in it; check the "
                              "profile's links, δ and ζ_min", Issue.END_NOT_FEASIBLE)
    if bool(ws.region.contains(np.stack([a, b]), tol=INSIDE_TOL_DEG).all()):
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
        res = iris_region(ws.feasible, ws.theta_deg(), ws.step_deg, lo, hi, np.stack([a, b]),
                    (E.C, E.d), limit)
        if bool(res.region.contains(np.stack([a, b]), tol=INSIDE_TOL_DEG).all()):
            return RegionChoice(res.region, "grown")
    rr = refined_region(ws, a, b, fine, samples=ex)
    return RegionChoice(rr.region, "refined", resolution_deg=rr.refinement.h_deg)


def region_containing(ws: Workspace, theta_a_deg: F, theta_b_deg: F) -> Region:
    """The region of :func:`choose_region`."""
    return choose_region(ws, theta_a_deg, theta_b_deg).region
