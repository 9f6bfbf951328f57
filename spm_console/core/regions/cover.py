"""A cover of the feasible set by several convex regions, and their overlaps as a graph.

The workspace's region P (:mod:`spm_console.core.regions.p_build`) holds most feasible
nodes, but near the boundary the feasible set is not convex. :func:`build_cover`
adds regions until a target fraction of the feasible nodes lies in at least one
of them (or a cap on their number is reached), then joins every two regions whose
intersection holds a ball of radius ≥ ``min_overlap_deg`` (default Δ/4: room for a
plan's switch sample) by an edge of the *region graph*.

Obstacles. P avoids the grid's obstacles (open cubes of half-width Δ around infeasible
nodes), and so do the cover's other regions by default (seed: the uncovered node deepest
inside the uncovered set; ~96.5 % of the 2° Agile Wrist grid's feasible nodes with 28
regions, in about a second). There a feasible node whose face neighbour in direction ±e_k is
infeasible ("terrace" node) lies on a face of that neighbour's cube, so a region holds such
nodes of one level per direction only (on the 2° Agile Wrist grid greedy growth needed ~400
regions for 99 %). The *refined* cover (``build_cover(refined=True)``, a build option: ~150k
exact checks and ten times more obstacles per region) avoids finer obstacles instead
(:mod:`spm_console.core.regions.cover_refine`): the grid cells with both feasible and infeasible
corners next to the nodes P leaves uncovered are refined to h = Δ/4, their fine nodes are
checked exactly by a flood fill from the feasible grid nodes (the runtime's own memoized
verdicts), and a region may enter such a cell
wherever the fine criterion of :class:`~spm_console.core.workspace.refine.RefinedCertifiedSet`
certifies it. A workspace without its models (no exact checks) falls back to the grid's cubes.

Growth of one refined region: the seed (and required point) is the uncovered feasible node, among
those whose surrounding fine cells are all clear, with the most uncovered nodes within
:data:`SEED_WINDOW` steps; IRIS steps (separating planes around the current ellipsoid, then
its maximum-volume inscribed ellipsoid) start from a ball of radius Δ there; the step
holding the most uncovered nodes wins, reduced to ``max_halfspaces`` rows with the uncovered
nodes as the objective. When the classified grid is invariant under the cyclic permutation
θ ↦ (θ2, θ3, θ1) (a symmetric manipulator on a cubic grid) every grown region is tried
with its two images.

**Certification.** P and the default cover's regions are built against the grid's cubes
(planes from :func:`~spm_console.core.regions.p_build.separating_planes`, reduced by
:func:`~spm_console.core.polytope.iris.reduce_halfspaces`, which only hands excluded cubes from one
plane to another; a permuted image avoids the permuted cubes, the same set on a symmetric
grid): they lie in the grid's certified set P′. Every refined region is kept only when
:func:`~spm_console.core.regions.cover_refine.region_clear` finds it clear of the refined obstacles
(exact: one row or an LP per obstacle) with its Chebyshev centre in a clear fine cell —
images included, since the fine verdicts need not be symmetric; then every point of it is
certified (grid or fine criterion; the argument is in :mod:`spm_console.core.regions.cover_refine`),
so the runtime's verification accepts plans through it. :func:`uncertified_regions` checks
both kinds independently of the obstacle list.

**Home connectivity.** Each region is convex and contains its seed, a feasible grid
node (feasible includes "connected to home through feasible nodes"). P contains
the home node, so every point of P joins home by a straight segment inside P. A
region joined to P by a path in the region graph joins home too: go straight to
the overlap's centre (inside both regions, convexity), then on to the next region,
and so on to P and home — every piece is a straight segment inside one region,
hence certified. Regions outside P's component of the graph (see
:meth:`RegionCover.components`) are joined to home only through the grid's
6-connected feasible nodes, not (yet) through regions; the planner cannot use them
from home.

**What stays uncovered** (refined). A feasible node with an infeasible fine node within h (the true
boundary passes within 0.5° of it on the 2° grid) can only lie on a region's face; these
~0.8 % of the nodes are not used as seeds.

Angles in degrees (θ) at this interface.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from spm_console.core.polytope.cover import RegionCover
from spm_console.core.polytope.iris import Frame, half_widths
from spm_console.core.polytope.region import INSIDE_TOL_DEG, Region
from spm_console.core.regions import p_build as rb
from spm_console.core.regions.cover_graph import S_CYCLIC, overlap_graph
from spm_console.core.regions.cover_grow import Grower, Reporter, deepest_seed, dense_seed
from spm_console.core.regions.cover_refine import (
    CLEAR_TOL_DEG,
    FineObstacles,
    refine_cells,
    region_clear,
    uncertified_cells,
)
from spm_console.core.workspace.refine import FineGrid
from spm_console.core.workspace.rowmap import RowMap, serial
from spm_console.errors import InfeasibleError, SolverError

if TYPE_CHECKING:
    from spm_console.core.workspace.data import Workspace

F = NDArray[np.float64]
B = NDArray[np.bool_]
I64 = NDArray[np.int64]

#: Fraction of the feasible nodes the cover aims at.
COVER_TARGET = 0.99
#: Most regions in a cover, P included (bounds the build time and the overlap graph).
COVER_MAX_REGIONS = 28
#: Most regions of a refined cover (``refined=True``), P included.
REFINED_MAX_REGIONS = 64
#: Most half-spaces of a cover region (P keeps the profile's limit).
COVER_HALFSPACES = 24
#: IRIS steps per cover region (the best one by new coverage is kept).
COVER_ITERS = 2
#: Smallest inscribed-ball radius of an overlap that makes an edge, in grid steps Δ.
MIN_OVERLAP_STEPS = 0.25
#: Points per membership test of P while the cover build starts (bounds the report gaps).
CONTAINS_CHUNK = 50_000
_S = S_CYCLIC


def cyclic_symmetric(ws: Workspace) -> bool:
    """True when the feasible nodes are invariant under θ ↦ (θ2, θ3, θ1) on equal axes."""
    a0, a1, a2 = ws.axes_deg
    if not (a0.shape == a1.shape == a2.shape and np.array_equal(a0, a1)
            and np.array_equal(a0, a2)):
        return False
    f = ws.feasible
    # g[a, b, c] = f[b, c, a]: node (a, b, c) feasible ⇔ node (b, c, a) feasible
    return bool(np.array_equal(f, np.transpose(f, (2, 0, 1))))


def _image(region: Region) -> Region:
    """σ(region) = {S θ : θ ∈ region} = {φ : A Sᵀ φ ≤ b}."""
    return Region(region.A @ _S.T, region.b.copy())


def _obstacles(ws: Workspace, covered: B, fidx: I64, fine: FineGrid | None, refined: bool,
               report: Callable[[float], None],
               rowmap: RowMap = serial) -> tuple[F, F, FineObstacles | None]:
    """(centres (n, 3) deg, half-widths (n,) deg, the refined set or None): with ``refined``
    and the workspace's models, refined near the nodes P leaves uncovered, else the grid's
    cubes."""
    if not refined or ws.model is None or ws.links is None:
        return rb.obstacle_nodes(ws.feasible, ws.theta_deg()), np.full(1, ws.step_deg), None
    want = np.zeros(ws.feasible.shape, bool)
    want[tuple(fidx[~covered].T)] = True
    fg = FineGrid(ws, rowmap=rowmap) if fine is None else fine
    report(0.0)
    obs = refine_cells(ws, fg, want, report)
    return obs.centres_deg, obs.half_deg, obs


def build_cover(
    ws: Workspace, target: float = COVER_TARGET, max_regions: int | None = None,
    max_halfspaces: int = COVER_HALFSPACES, iters: int = COVER_ITERS,
    min_overlap_deg: float | None = None, progress: Callable[[float], None] | None = None,
    fine: FineGrid | None = None, refined: bool = False, rowmap: RowMap = serial,
) -> RegionCover:
    """Grow regions from the workspace's P (``ws.region``) until ``target`` of the feasible
    nodes are covered or ``max_regions`` regions exist (default :data:`COVER_MAX_REGIONS`,
    refined :data:`REFINED_MAX_REGIONS`), then build the overlap graph. ``min_overlap_deg``
    defaults to MIN_OVERLAP_STEPS · Δ.

    By default the regions avoid the grid's obstacle cubes and seeds are the uncovered nodes
    deepest inside the uncovered set (fast; ~96.5 % on the 2° Agile Wrist grid). With
    ``refined`` (and the workspace's models) they avoid the refined obstacles instead
    (:mod:`spm_console.core.regions.cover_refine`; ``fine`` memoizes the exact checks), seeds go by
    local density, and every region is checked clear (≥ 99 %, several times slower). ``rowmap``
    runs the exact checks of a ``fine`` grid made here and the overlap graph's LPs
    (:mod:`spm_console.core.workspace.rowmap`)."""
    from scipy.spatial import QhullError  # here: the runtime only loads a cover

    if max_regions is None:
        max_regions = REFINED_MAX_REGIONS if refined else COVER_MAX_REGIONS
    t0 = time.perf_counter()
    report = Reporter(progress)
    report(0.0, force=True)
    rmin = MIN_OVERLAP_STEPS * ws.step_deg if min_overlap_deg is None else float(min_overlap_deg)
    f = ws.feasible
    theta = ws.theta_deg()
    fidx = np.argwhere(f)
    fpts = theta[f]
    home = np.asarray(theta[ws.home_index], float)
    regions: list[Region] = [ws.region]
    seeds: list[F] = [home]
    covered = np.zeros(len(fpts), bool)
    for c in range(0, len(fpts), CONTAINS_CHUNK):  # in pieces: 1.4 s for P on the 1° grid
        covered[c:c + CONTAINS_CHUNK] = ws.region.contains(fpts[c:c + CONTAINS_CHUNK],
                                                          tol=INSIDE_TOL_DEG)
        report(0.0)
    need = int(np.ceil(target * len(fpts)))
    refine_share = 0.5 if refined else 0.0
    obs: FineObstacles | None = None
    if int(covered.sum()) < need:
        centres, half, obs = _obstacles(ws, covered, fidx, fine, refined,
                                        lambda x: report(refine_share * x), rowmap)
    else:
        centres, half = np.zeros((0, 3)), np.zeros(1)
    t_refine = time.perf_counter() - t0 if obs is not None else 0.0
    report(refine_share)
    symmetric = cyclic_symmetric(ws)
    orbits = symmetric
    lo, hi = ws.range_deg()
    frame = Frame(np.full(3, 0.5 * (lo + hi)), 0.5 * (hi - lo))
    frac = [refine_share]
    grower = Grower(frame, frame.to_x(centres), half_widths(half, len(centres)) / frame.s,
                     max_halfspaces, iters, ws.step_deg, tick=lambda: report(frac[0]))
    # a node a region can hold in its interior: every fine cell around it clear
    easy = obs.node_clear(fidx) if obs is not None else np.ones(len(fidx), bool)
    report(refine_share)
    tried = np.zeros(len(fidx), bool)
    pos = np.full(f.shape, -1, np.int64)
    pos[f] = np.arange(len(fidx))
    group = 3 if symmetric else 1
    start = int(covered.sum())
    while int(covered.sum()) < need and len(regions) + group <= max_regions:
        cand = ~covered & ~tried & easy
        if not cand.any():
            break
        j = dense_seed(f, fidx, ~covered, cand) if obs is not None else deepest_seed(f, fidx, cand)
        tried[j] = True
        seed = np.asarray(fpts[j], float)
        try:
            reg = grower.grow(seed, fpts[~covered])
        except (InfeasibleError, SolverError, QhullError):
            continue
        new = [reg, _image(reg), _image(_image(reg))] if symmetric else [reg]
        news = [seed, S_CYCLIC @ seed, S_CYCLIC @ S_CYCLIC @ seed] if symmetric else [seed]
        for r, s in zip(new, news, strict=True):
            # the refined obstacles need not be symmetric: every region is checked
            report(frac[0])
            if obs is not None and not region_clear(r, obs):
                orbits = False
                continue
            rest = ~covered
            covered[rest] = r.contains(fpts[rest], tol=INSIDE_TOL_DEG)
            regions.append(r)
            seeds.append(s)
        for s in news[1:]:
            k = ws.index_of(s)
            if k is not None and pos[k] >= 0:
                tried[pos[k]] = True
        done = (int(covered.sum()) - start) / max(need - start, 1)
        frac[0] = refine_share + (0.9 - refine_share) * done
        report(frac[0], force=True)
    edges, pts, rad = overlap_graph(tuple(regions), rmin, orbits,
                                    tick=lambda x: report(0.9 + 0.1 * x), rowmap=rowmap)
    report(1.0, force=True)
    return RegionCover(
        regions=tuple(regions), seeds_deg=np.array(seeds, float).reshape(-1, 3), edges=edges,
        edge_points_deg=pts, edge_radius_deg=rad, min_overlap_deg=rmin,
        covered=float(covered.mean()) if len(fpts) else 0.0,
        seconds=time.perf_counter() - t0,
        resolution_deg=None if obs is None else obs.h_deg,
        refined_cells=0 if obs is None else obs.refined_cells,
        fine_nodes=0 if obs is None else obs.fine_nodes,
        refine_seconds=t_refine,
    )


def uncertified_regions(ws: Workspace, cover: RegionCover, fine: FineGrid | None = None,
                        tol_deg: float = CLEAR_TOL_DEG) -> list[int]:
    """Regions not inside the certified set (grid or fine criterion of
    :class:`~spm_console.core.workspace.refine.RefinedCertifiedSet`): empty for a certified cover.
    Exact and independent of the build's obstacle list
    (:func:`~spm_console.core.regions.cover_refine.uncertified_cells`: every fine cell of a bad grid
    cell the region's interior meets must have exactly feasible corners; ``fine`` memoizes
    the verdicts, a fresh :class:`~spm_console.core.workspace.refine.FineGrid` by default)."""
    fg = FineGrid(ws) if fine is None else fine
    return [k for k, r in enumerate(cover.regions)
            if len(uncertified_cells(ws, r, fg, tol_deg))]
