"""A region around a segment near the boundary, certified at the fine resolution h = Δ/4.

On the grid a region must avoid the open cube of half-width Δ around every infeasible grid
node, so a segment passing closer than Δ to one is refused although it may be feasible
everywhere. Here the grid nodes near the segment are *refined* and the region avoids, for
them, only the open cubes of half-width h around their infeasible fine nodes
(:mod:`spm_console.core.workspace.refine`):

1. **refined nodes** N: every infeasible grid node within L∞ distance < :data:`REACH_STEPS`·Δ
   of the segment;
2. every fine node in the closed cube of half-width Δ + h around each node of N is checked
   exactly (so every fine node within h of any point of the node's open Δ-cube is known);
3. **obstacles**: the open h-cube around each infeasible fine node of step 2; the open
   Δ-cube around every infeasible grid node not in N that has a feasible 26-neighbour
   (the grid's IRIS obstacles) or is a 26-neighbour of a node of N;
4. the segment check: in the grid box, outside the h-cubes of step 2 and the Δ-cubes of
   *every* infeasible grid node not in N, and feasible at exact samples every ≤ h;
5. IRIS around the segment against the obstacles of step 3.

Why the region R is certified (every θ ∈ R is in
:class:`~spm_console.core.workspace.refine.RefinedCertifiedSet`): call *unlisted* the infeasible grid
nodes that are neither in N nor obstacles, and U their open Δ-cubes. The segment's ends lie
outside U (step 4). If R met U, the segment from an end to a point of R ∩ U would first
touch the boundary of some unlisted cube at q ∈ R, |q − m|∞ = Δ; the grid node n = m + Δ·s
(s_i = sign(q_i − m_i) on the axes where |q_i − m_i| = Δ, else 0) is a 26-neighbour of m
with |q − n|∞ < Δ, infeasible (m has no feasible 26-neighbour) and not unlisted (q ∉ U):
an obstacle (then q lies in its open cube, impossible) or in N (then m, its 26-neighbour,
would be an obstacle). So R ∩ U = ∅. Now take θ ∈ R not certified by the grid: some
infeasible grid node m has |θ − m|∞ < Δ; m is listed, and not an obstacle, so m ∈ N; every
fine node within h of θ lies within Δ + h of m, was checked in step 2, and is feasible
(else θ would lie in its h-cube). So the fine criterion certifies θ.

Angles in degrees.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from spm_console.core.polytope.ellipsoid import inscribed_ellipsoid
from spm_console.core.polytope.region import INSIDE_TOL_DEG, Region
from spm_console.core.regions.p_build import iris_region
from spm_console.core.workspace.refine import FineGrid
from spm_console.core.workspace.segment_check import (
    CubeSet,
    ExactSamples,
    check_range,
    check_segment,
    exact_samples,
    node_reason,
    segment_entry,
)
from spm_console.errors import InfeasibleError

if TYPE_CHECKING:
    from spm_console.core.workspace.data import Workspace

F = NDArray[np.float64]
B = NDArray[np.bool_]
I64 = NDArray[np.int64]

#: Infeasible grid nodes within this L∞ distance of the segment (in grid steps Δ) are
#: refined: more than 1 so the region has room on every side of the segment.
REACH_STEPS = 1.5


def _fmt(t: F) -> str:
    return "[" + ", ".join(f"{x:.2f}" for x in t) + "]"


@dataclass(frozen=True)
class Refinement:
    """The mixed obstacle set around one segment (θ in degrees)."""

    refined: I64
    """Flat indices of the refined grid nodes N."""
    fine_bad: I64
    """Fine indices (k, 3) of the infeasible fine nodes checked around N."""
    fine_bad_deg: F
    """Their θ, deg."""
    grid_obstacles: F
    """θ (deg) of the grid obstacles of step 3 (half-width Δ)."""
    grid_unrefined_bad: I64
    """Flat indices of every infeasible grid node not in N (the segment check's Δ-cubes)."""
    fine_nodes: int
    """Fine nodes in the cubes of step 2."""
    evaluated: int
    """Of them, checked exactly by this call (the rest were memoized or grid nodes)."""
    h_deg: float
    seconds: float

    def obstacles(self, step_deg: float) -> tuple[F, F]:
        """(centres (n, 3), half-widths (n,)) deg, for IRIS."""
        centres = np.vstack([self.grid_obstacles, self.fine_bad_deg])
        half = np.r_[np.full(len(self.grid_obstacles), step_deg),
                     np.full(len(self.fine_bad_deg), self.h_deg)]
        return centres, half


def refine_near(ws: Workspace, fine: FineGrid, a: F, b: F,
                reach_steps: float = REACH_STEPS) -> Refinement:
    """Steps 1–3 of the module docstring for the segment a→b (deg)."""
    from scipy import ndimage  # here: only a build needs it (~0.4 s to import)

    t0 = time.perf_counter()
    before = fine.evaluated
    feasible = ws.feasible
    theta = ws.theta_deg().reshape(-1, 3)
    bad = np.flatnonzero(~feasible.ravel())
    t_in, _ = segment_entry(a, b, theta[bad], reach_steps * ws.step_deg)
    refined = bad[np.isfinite(t_in)]
    cube = fine.cubes(theta[refined], fine.refine + 1)
    ok = fine.verdicts(cube) if len(cube) else np.zeros(0, bool)
    fine_bad = cube[~ok]
    flat_n = np.zeros(feasible.size, bool)
    flat_n[refined] = True
    in_n = flat_n.reshape(feasible.shape)
    k26 = np.ones((3, 3, 3), bool)
    listed = ~feasible & ~in_n & (ndimage.binary_dilation(feasible, structure=k26)
                                  | ndimage.binary_dilation(in_n, structure=k26))
    unrefined = np.flatnonzero((~feasible & ~in_n).ravel())
    return Refinement(
        refined=refined, fine_bad=fine_bad, fine_bad_deg=fine.theta_deg(fine_bad),
        grid_obstacles=np.asarray(ws.theta_deg()[listed]), grid_unrefined_bad=unrefined,
        fine_nodes=len(cube), evaluated=fine.evaluated - before, h_deg=fine.step_deg,
        seconds=time.perf_counter() - t0,
    )


def check_segment_refined(ws: Workspace, fine: FineGrid, ref: Refinement, a: F, b: F,
                          samples: ExactSamples | None = None) -> None:
    """Step 4: raise :class:`InfeasibleError` (naming the first θ and why) unless a→b is
    certified at the fine resolution."""
    theta = ws.theta_deg().reshape(-1, 3)
    grid = CubeSet(theta[ref.grid_unrefined_bad], float(ws.step_deg), f"Δ = {ws.step_deg:g}°",
                   lambda j: node_reason(ws, int(ref.grid_unrefined_bad[j])))
    fine_set = CubeSet(ref.fine_bad_deg, fine.step_deg, f"h = {fine.step_deg:g}°",
                       lambda j: (f"fine node {_fmt(ref.fine_bad_deg[j])}° (the grid refined "
                                  f"{fine.refine}×), which is " + fine.reason(ref.fine_bad[j])))
    check_segment(ws, a, b, [grid, fine_set], samples,
                  hint=f"certified only where every fine node within h = {fine.step_deg:g}° is "
                       "feasible, it is not certified there (too close to the boundary at this "
                       "resolution)")


@dataclass(frozen=True)
class RefinedRegion:
    """A region certified at the fine resolution, and what it cost."""

    region: Region
    refinement: Refinement
    seconds: float
    """Wall time of the whole construction (refinement, checks, IRIS), s."""


def refined_region(ws: Workspace, a: F, b: F, fine: FineGrid | None = None,
                   samples: ExactSamples | None = None,
                   reach_steps: float = REACH_STEPS) -> RefinedRegion:
    """Steps 1–5 of the module docstring: a region containing a and b (deg), or
    :class:`InfeasibleError` saying why not."""

    t0 = time.perf_counter()
    fg = FineGrid(ws) if fine is None else fine
    check_range(ws, a, b)
    ex = exact_samples(ws, a, b) if samples is None else samples
    ref = refine_near(ws, fg, a, b, reach_steps)
    check_segment_refined(ws, fg, ref, a, b, ex)
    lo, hi = ws.range_deg()
    E = inscribed_ellipsoid(ws.region.A, ws.region.b)
    limit = max(ws.region.halfspaces, int(ws.region_info.get("max_halfspaces", 64)))
    ends = np.stack([a, b])
    res = iris_region(ws.feasible, ws.theta_deg(), ws.step_deg, lo, hi, ends, (E.C, E.d), limit,
                obstacles=ref.obstacles(ws.step_deg))
    if not bool(res.region.contains(ends, tol=INSIDE_TOL_DEG).all()):
        raise InfeasibleError("could not build a convex region containing both configurations "
                              f"(refined to h = {fg.step_deg:g}° near the segment)")
    return RefinedRegion(res.region, ref, time.perf_counter() - t0)
