"""The overlap graph of a region cover: which regions share a ball of a given radius.

Angles in degrees at this interface.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import numpy as np
from numpy.typing import NDArray

from spm_console.core.polytope.region import Region
from spm_console.core.workspace.rowmap import RowMap, serial

F = NDArray[np.float64]
I64 = NDArray[np.int64]

#: Cyclic permutation θ ↦ (θ2, θ3, θ1) as a matrix: σ(θ) = S θ.
S_CYCLIC = np.eye(3)[[1, 2, 0]]


def _vertices(region: Region) -> F | None:
    """The region's vertices, or None when qhull cannot tell (no pruning for it)."""
    from scipy.spatial import QhullError  # (loaded by Region.vertices anyway)

    try:
        return region.vertices()
    except QhullError:  # too thin for qhull
        return None


def _bbox(V: F | None) -> tuple[F, F]:
    if V is None:
        return np.full(3, -np.inf), np.full(3, np.inf)
    if len(V) == 0:
        return np.full(3, np.inf), np.full(3, -np.inf)
    return V.min(0), V.max(0)


def _apart(r1: Region, V2: F | None, radius: float) -> bool:
    """True when a row a·θ ≤ b of ``r1`` (unit rows) leaves the polytope with vertices ``V2``
    less than 2·radius: every point of it has a·θ > b − 2·radius, so no ball of that radius
    lies in both (a centre c would need min a·V2 + radius ≤ a·c ≤ b − radius)."""
    if V2 is None or len(V2) == 0:
        return False
    Rn = r1.normalized()
    low = (V2 @ Rn.A.T).min(0)
    return bool((low > Rn.b - 2.0 * radius + 1e-9 * max(1.0, float(np.abs(V2).max()))).any())


def _pair_balls(regions: tuple[Region, ...], i: I64, j: I64) -> tuple[F, F]:
    """Chebyshev centres (n, 3) and radii (n,) of regions[i_k] ∩ regions[j_k] (row-wise)."""
    centres = np.zeros((len(i), 3))
    radii = np.zeros(len(i))
    for k, (a, b) in enumerate(zip(i.tolist(), j.tolist(), strict=True)):
        both = Region(np.vstack([regions[a].A, regions[b].A]), np.r_[regions[a].b, regions[b].b])
        centres[k], radii[k] = both.chebyshev()
    return centres, radii


def overlap_graph(regions: tuple[Region, ...], min_radius_deg: float,
                  symmetric: bool = False,
                  tick: Callable[[float], None] | None = None,
                  rowmap: RowMap = serial) -> tuple[I64, F, F]:
    """Edges (m, 2), Chebyshev centres (m, 3) and radii (m,) of the pairwise intersections
    with an inscribed ball of radius ≥ ``min_radius_deg`` (one LP per pair whose bounding
    boxes, shrunk by that radius, still meet and that no row of one region leaves the other
    thinner than twice that radius). With ``symmetric`` the regions come in
    orbits (i, i+1, i+2 = r, σr, σ²r) after region 0, and a pair's images are not solved
    again. ``tick(fraction)`` is called as the pairs are screened (progress; may raise to
    cancel); ``rowmap`` runs the LPs (:mod:`spm_console.core.workspace.rowmap`)."""
    k = len(regions)
    verts = [_vertices(r) for r in regions]
    boxes = [_bbox(V) for V in verts]
    lo = np.array([b[0] for b in boxes]).reshape(k, 3)
    hi = np.array([b[1] for b in boxes]).reshape(k, 3)
    done: set[tuple[int, int]] = set()

    def orbit(i: int) -> list[int]:
        if not symmetric or i == 0:
            return [i, i, i]
        base = 1 + 3 * ((i - 1) // 3)
        o = (i - 1) % 3
        return [base + (o + s) % 3 for s in range(3)]

    # the pairs to solve (one per orbit of pairs) and the keys each one's images stand for
    todo: list[tuple[int, int]] = []
    stands: list[list[tuple[int, tuple[int, int]]]] = []
    for i in range(k):
        if tick is not None:
            tick(0.5 * i / k)
        for j in range(i + 1, k):
            if (i, j) in done:
                continue
            if ((np.minimum(hi[i], hi[j]) - np.maximum(lo[i], lo[j])) < 2 * min_radius_deg).any():
                continue
            if (_apart(regions[i], verts[j], min_radius_deg)
                    or _apart(regions[j], verts[i], min_radius_deg)):
                continue
            if symmetric and (i == 0 or j == 0):
                images = [(i, j)]  # P has no images
            else:
                oi, oj = orbit(i), orbit(j)
                images = [(oi[s], oj[s]) for s in range(3)] if symmetric else [(i, j)]
            mine = []
            for s, (a, b) in enumerate(images):
                key = (min(a, b), max(a, b))
                if key not in done:
                    done.add(key)
                    mine.append((s, key))
            todo.append((i, j))
            stands.append(mine)
    pairs = np.array(todo, np.int64).reshape(-1, 2)
    centres, radii = rowmap(partial(_pair_balls, regions), pairs[:, 0], pairs[:, 1])
    if tick is not None:
        tick(1.0)
    found: dict[tuple[int, int], tuple[F, float]] = {}
    for c, r, mine in zip(centres, radii, stands, strict=True):
        if r >= min_radius_deg:
            for s, key in mine:
                found[key] = (np.linalg.matrix_power(S_CYCLIC, s) @ c, float(r))
    keys = sorted(found)
    edges = np.array(keys, np.int64).reshape(-1, 2)
    pts = np.array([found[q][0] for q in keys], float).reshape(-1, 3)
    rad = np.array([found[q][1] for q in keys], float)
    return edges, pts, rad
