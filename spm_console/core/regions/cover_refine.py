"""Obstacles of the region cover refined near the boundary: grid cells checked at h = Δ/4.

On the grid a region must avoid every *bad cell* (a grid cell with an infeasible corner):
there the grid certifies nothing, so a feasible node next to an infeasible one ("terrace"
node) can only sit on a region's face. :class:`~spm_console.core.workspace.refine.RefinedCertifiedSet`
also certifies θ when the ≤ 8 fine nodes within L∞ distance < h of it (the corners of its
*fine cell*, the grid cell split :data:`~spm_console.core.workspace.refine.REFINE` times per axis) are
exactly feasible. Here the bad cells with a feasible corner (*mixed* cells; optionally only
those holding a node still to cover) are **refined**: their fine nodes are checked with the
same memoized exact verdicts the runtime uses (:class:`~spm_console.core.workspace.refine.FineGrid`),
by a flood fill from the feasible grid nodes (a node is checked when a face neighbour was
found feasible: the interior of infeasible blobs is never checked, and a node left unchecked
counts as not exactly feasible; on the 2° Agile Wrist grid every feasible fine node is
reached, 152k checks instead of 239k). The obstacles are then

* every open fine cell of a refined cell with a corner that is not known exactly feasible;
* every open bad cell that is not refined (blocked: no fine node of it is known).

A fine cell that is neither is *clear*. Only obstacles with a face neighbour that is clear
(a clear fine cell or a cell holding one) are handed to IRIS (the *frontier*).

**Why a region R avoiding the frontier is certified** (R closed, convex, full-dimensional,
inside the grid box, and its Chebyshev centre in a clear fine cell — checked for every
region). (1) R avoids every obstacle: if not, take a point of int R in an obstacle and the
centre c; a generic segment between them crosses fine faces one at a time at 2-D face
points, so at its first entry into an obstacle it passes from a clear fine cell into that
obstacle through a common face: the obstacle is on the frontier, a contradiction. (2) Take
θ ∈ R. If every grid node within < Δ of θ (the corners of the grid face or cell whose
relative interior holds θ) is feasible, the grid certifies θ. Otherwise every grid cell
around θ is bad, so every fine cell around θ lies in a bad cell; int R meets one of them
near θ, which by (1) is clear; its corners include every fine node within < h of θ, all
exactly feasible: the fine criterion certifies θ.

Angles in degrees at this interface.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from spm_console.core.polytope.region import INSIDE_TOL_DEG, Region
from spm_console.core.workspace.refine import FineGrid

if TYPE_CHECKING:
    from spm_console.core.workspace.data import Workspace

F = NDArray[np.float64]
B = NDArray[np.bool_]
I64 = NDArray[np.int64]

#: Fine nodes checked per call of the exact verdicts (bounds the gap between progress reports).
VERDICT_CHUNK = 24000
#: Grid cells whose fine nodes are listed at once (bounds the gap between progress reports).
CELL_CHUNK = 2000
#: A box is clear of a region when one row's minimum over it is at least b − this (deg), or
#: when region ∩ closed box holds no ball of radius above it: the membership tolerance (a
#: region may reach into an obstacle box by no more than a point counted inside it may lie
#: outside it).
CLEAR_TOL_DEG = INSIDE_TOL_DEG
#: 6-connectivity (faces): ``scipy.ndimage.generate_binary_structure(3, 1)``.
_S6 = np.zeros((3, 3, 3), bool)
_S6[1, 1, :] = _S6[1, :, 1] = _S6[:, 1, 1] = True


def _corners_all(a: B) -> B:
    """(n−1, …) True where all 2×2×2 corners of the cell are True in the node array ``a``."""
    n = a.shape
    out = np.ones(tuple(s - 1 for s in n), bool)
    for d in np.ndindex(2, 2, 2):
        out &= a[d[0]:d[0] + n[0] - 1, d[1]:d[1] + n[1] - 1, d[2]:d[2] + n[2] - 1]
    return out


def _corners_count(a: B) -> NDArray[np.int64]:
    n = a.shape
    out = np.zeros(tuple(s - 1 for s in n), np.int64)
    for d in np.ndindex(2, 2, 2):
        out += a[d[0]:d[0] + n[0] - 1, d[1]:d[1] + n[1] - 1, d[2]:d[2] + n[2] - 1]
    return out


def _up(a: B, r: int) -> B:
    """Cell mask refined r times per axis (each cell → r³ fine cells)."""
    return np.asarray(np.repeat(np.repeat(np.repeat(a, r, 0), r, 1), r, 2))


def _refined_mask(refined: B, r: int,
                  progress: Callable[[float], None] | None = None) -> B:
    """Fine-node mask of the refined grid cells (their corners and faces included)."""
    cells = np.argwhere(refined)
    k = np.arange(r + 1)
    offs = np.stack(np.meshgrid(k, k, k, indexing="ij"), -1).reshape(-1, 3)
    mask = np.zeros(tuple(int(s) * r + 1 for s in refined.shape), bool)
    for c in range(0, len(cells), CELL_CHUNK):
        idx = (cells[c:c + CELL_CHUNK, None, :] * r + offs[None]).reshape(-1, 3)
        mask[idx[:, 0], idx[:, 1], idx[:, 2]] = True
        if progress is not None:
            progress(0.0)
    return mask


def _flood_verdicts(fine: FineGrid, ws_feasible: B, inside: B,
                    progress: Callable[[float], None] | None = None) -> B:
    """Fine nodes of ``inside`` known exactly feasible, found by a flood fill: from the
    feasible grid nodes in ``inside``, the face neighbours (in ``inside``) of every node found
    feasible are checked, wave after wave. A node no wave reaches is never checked (it
    counts as not feasible: its cells stay obstacles). Returns the feasible mask."""
    r = fine.refine
    shape = np.array(inside.shape)
    ok = np.zeros(inside.shape, bool)
    seen = np.zeros(inside.shape, bool)
    grid = np.zeros(inside.shape, bool)
    grid[::r, ::r, ::r] = True
    seen[grid] = True
    ok[::r, ::r, ::r] = ws_feasible
    ok &= inside
    wave = np.argwhere(ok)
    total = max(int(inside.sum()), 1)
    checked = 0
    steps = np.vstack([np.eye(3, dtype=np.int64), -np.eye(3, dtype=np.int64)])
    while len(wave):
        nb = (wave[:, None, :] + steps[None]).reshape(-1, 3)
        nb = nb[np.all((nb >= 0) & (nb < shape), axis=1)]
        nb = nb[inside[tuple(nb.T)] & ~seen[tuple(nb.T)]]
        flat = np.unique(np.ravel_multi_index(tuple(nb.T), inside.shape))
        nb = np.column_stack(np.unravel_index(flat, inside.shape)).astype(np.int64)
        seen[tuple(nb.T)] = True
        good = np.zeros(len(nb), bool)
        for s in range(0, len(nb), VERDICT_CHUNK):
            good[s:s + VERDICT_CHUNK] = fine.verdicts(nb[s:s + VERDICT_CHUNK])
            checked += len(nb[s:s + VERDICT_CHUNK])
            if progress is not None:  # a fraction of the refined nodes (not all are checked)
                progress(min(1.0, checked / total))
        wave = nb[good]
        ok[tuple(wave.T)] = True
    return ok


def bad_cells(feasible: B) -> tuple[B, B]:
    """(bad, mixed) grid-cell masks: a corner infeasible / and a corner feasible too."""
    k = _corners_count(feasible)
    return np.asarray(k < 8), np.asarray((k > 0) & (k < 8))


@dataclass(frozen=True)
class FineObstacles:
    """The cover's refined obstacle set (module docstring), θ in degrees."""

    centres_deg: F
    """(n, 3) centres of the frontier obstacles (open boxes)."""
    half_deg: F
    """(n,) their half-widths: Δ/2 (a blocked grid cell) or h/2 (a fine cell)."""
    clear: B
    """Fine-cell mask: True where an open fine cell is certified (clear)."""
    origin_deg: F
    h_deg: float
    refine: int
    refined_cells: int
    """Grid cells refined."""
    fine_nodes: int
    """Fine nodes of the refined cells (grid nodes included)."""
    evaluated: int
    """Of them, checked exactly by this build (the rest were grid nodes or memoized)."""
    seconds: float

    def clear_at(self, theta_deg: F) -> bool:
        """True when the fine cell holding θ (deg; on a fine plane: the cell above it) is
        clear; False outside the grid box."""
        u = np.floor((np.asarray(theta_deg, float) - self.origin_deg) / self.h_deg)
        i = u.astype(np.int64)
        if (i < 0).any() or (i >= np.array(self.clear.shape)).any():
            return False
        return bool(self.clear[i[0], i[1], i[2]])

    def node_clear(self, idx: I64) -> B:
        """(n,) True where every fine cell around grid nodes ``idx`` (n, 3) in the box is
        clear (a region may hold the node in its interior)."""
        r = self.refine
        ok = np.ones(len(idx), bool)
        shape = np.array(self.clear.shape)
        for d in np.ndindex(2, 2, 2):
            c = np.asarray(idx, np.int64) * r - 1 + np.array(d)
            on = np.all((c >= 0) & (c < shape), 1)
            cc = np.clip(c, 0, shape - 1)
            ok &= ~on | self.clear[cc[:, 0], cc[:, 1], cc[:, 2]]
        return ok


def refine_cells(ws: Workspace, fine: FineGrid, want_nodes: B | None = None,
                 progress: Callable[[float], None] | None = None) -> FineObstacles:
    """Refine the mixed grid cells (those with a corner in ``want_nodes`` when given) and build
    the obstacle set of the module docstring. ``progress(fraction)`` after every chunk of
    exact checks."""
    from scipy import ndimage  # here: only a build needs it (~0.4 s to import)

    t0 = time.perf_counter()
    before = fine.evaluated
    r = fine.refine
    bad, mixed = bad_cells(ws.feasible)
    refined = mixed if want_nodes is None else mixed & ~_corners_all(~np.asarray(want_nodes))
    if progress is not None:
        progress(0.0)
    inside = _refined_mask(refined, r, progress)
    if progress is not None:
        progress(0.0)
    ok_nodes = _flood_verdicts(fine, ws.feasible, inside, progress)
    fine_refined = _up(refined, r)
    clear = ~_up(bad, r)
    if progress is not None:
        progress(1.0)
    clear |= fine_refined & _corners_all(ok_nodes)
    del ok_nodes
    if progress is not None:
        progress(1.0)
    # frontier: fine obstacles of refined cells next to a clear fine cell; blocked grid cells
    # next to a grid cell holding a clear fine cell
    touch = ndimage.binary_dilation(clear, structure=_S6)
    if progress is not None:
        progress(1.0)
    fine_front = np.argwhere(fine_refined & ~clear & touch)
    del touch
    if progress is not None:
        progress(1.0)
    n = bad.shape
    has_clear = np.asarray(clear.reshape(n[0], r, n[1], r, n[2], r).any(axis=(1, 3, 5)))
    blocked = bad & ~refined
    coarse_front = np.argwhere(blocked & ndimage.binary_dilation(has_clear, structure=_S6))
    step = float(ws.step_deg)
    h = fine.step_deg
    org = fine.origin_deg
    centres = np.vstack([org + (coarse_front + 0.5) * step, org + (fine_front + 0.5) * h])
    half = np.r_[np.full(len(coarse_front), 0.5 * step), np.full(len(fine_front), 0.5 * h)]
    return FineObstacles(
        centres_deg=centres, half_deg=half, clear=clear, origin_deg=org.copy(), h_deg=h,
        refine=r, refined_cells=int(refined.sum()), fine_nodes=int(inside.sum()),
        evaluated=fine.evaluated - before, seconds=time.perf_counter() - t0,
    )


#: The signs of the 8 corners of a box.
_OCTANTS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)


def boxes_met(region: Region, lo_deg: F, hi_deg: F, tol: float = CLEAR_TOL_DEG) -> B:
    """(n,) which closed boxes [lo, hi] (n, 3) deg the region's interior meets (a ball of
    radius > ``tol`` in region ∩ box). Exact: a box that no single row excludes, and where
    neither the centre nor a point halfway to a corner already holds such a ball, is settled
    by an LP (the largest ball)."""
    Rn = region.normalized()
    c = 0.5 * (lo_deg + hi_deg)
    hw = 0.5 * (hi_deg - lo_deg)
    mins = c @ Rn.A.T - hw @ np.abs(Rn.A).T
    maybe = ~(mins >= Rn.b - tol).any(axis=1)
    # a ball at a point p of the box: radius p's distance to the nearer of the box's and the
    # (unit-row) region's faces; larger than tol, the LP's optimum is too. p: the centre, then
    # the 8 points halfway to the corners (a box reaching into the region by a corner)
    out = maybe & (np.minimum((Rn.b - c @ Rn.A.T).min(axis=1), hw.min(axis=1)) > tol)
    for sign in _OCTANTS:
        rest = np.flatnonzero(maybe & ~out)
        if not len(rest):
            break
        p = c[rest] + 0.5 * hw[rest] * sign
        ball = np.minimum((Rn.b - p @ Rn.A.T).min(axis=1), 0.5 * hw[rest].min(axis=1))
        out[rest[ball > tol]] = True
    box = np.vstack([np.eye(3), -np.eye(3)])
    for k in np.flatnonzero(maybe & ~out):
        both = Region(np.vstack([Rn.A, box]), np.r_[Rn.b, hi_deg[k], -lo_deg[k]])
        out[k] = both.chebyshev()[1] > tol
    return out


def region_clear(region: Region, obs: FineObstacles, tol: float = CLEAR_TOL_DEG) -> bool:
    """True when the region meets no frontier obstacle and its Chebyshev centre lies in a
    clear fine cell (the conditions of the module docstring's argument)."""
    from scipy.spatial import QhullError  # (loaded by Region.vertices anyway)

    centre, radius = region.chebyshev()
    if radius <= tol or not obs.clear_at(centre):
        return False
    hw = obs.half_deg[:, None]
    lo, hi = obs.centres_deg - hw, obs.centres_deg + hw
    # only boxes meeting the region's bounding box can meet the region
    try:
        V = region.vertices(interior=centre)
    except QhullError:  # too thin for qhull: every box is tested
        V = np.zeros((0, 3))
    if len(V):
        near = np.flatnonzero(np.all((lo < V.max(0) + tol) & (hi > V.min(0) - tol), axis=1))
        lo, hi = lo[near], hi[near]
    return not bool(boxes_met(region, lo, hi, tol).any())


def uncertified_cells(ws: Workspace, region: Region, fine: FineGrid,
                      tol: float = CLEAR_TOL_DEG) -> F:
    """Independent check of one region against the certified set's definition (no frontier,
    no obstacle list): the fine cells (as lower corners, deg) inside bad grid cells that the
    region's interior meets although a corner is not exactly feasible (``fine.verdicts``).
    Empty for a certified region."""
    bad, _ = bad_cells(ws.feasible)
    step = float(ws.step_deg)
    org = np.array([a[0] for a in ws.axes_deg], float)
    cells = np.argwhere(bad)
    lo = org + cells * step
    met = cells[boxes_met(region, lo, lo + step, tol)]
    if len(met) == 0:
        return np.zeros((0, 3))
    r = fine.refine
    h = fine.step_deg
    sub = np.stack(np.meshgrid(*(np.arange(r),) * 3, indexing="ij"), -1).reshape(-1, 3)
    fcells = (met[:, None, :] * r + sub[None]).reshape(-1, 3)
    flo = org + fcells * h
    hit = fcells[boxes_met(region, flo, flo + h, tol)]
    corners = np.stack(np.meshgrid(*(np.arange(2),) * 3, indexing="ij"), -1).reshape(-1, 3)
    v = fine.verdicts((hit[:, None, :] + corners[None]).reshape(-1, 3)).reshape(len(hit), 8)
    return np.asarray(org + hit[~v.all(axis=1)] * h)
