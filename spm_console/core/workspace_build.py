"""The whole workspace build: the grid (Algorithm 2), then the convex region P (eq. (30))
and the cover of the feasible set by convex regions with their overlap graph.

It sits above both :mod:`spm_console.core.workspace` (the grid and its data) and
:mod:`spm_console.core.regions` (P and the cover, built from the grid), so that neither
package depends on the other's top. Degrees and mm at the interface.
"""

from __future__ import annotations

import time
from dataclasses import replace

from spm_console.core.regions.cover import build_cover
from spm_console.core.regions.p_build import build_region
from spm_console.core.workspace.build import build_grid, stage_progress
from spm_console.core.workspace.data import GridSpec, Progress, Workspace
from spm_console.core.workspace.rowmap import RowMap, serial

#: Version of the workspace algorithm and its stored arrays (part of the cache key):
#: bump it whenever the grid, classification or region construction changes.
FORMAT_VERSION = 6


def build_workspace(spec: GridSpec, progress: Progress | None = None,
                    cover: bool = True, refined_cover: bool = False,
                    rowmap: RowMap = serial) -> Workspace:
    """Grid (Algorithm 2) plus the convex region P and (``cover``) the region cover, refined
    near the boundary with ``refined_cover`` (:func:`~spm_console.core.regions.cover.build_cover`);
    ``progress(stage, fraction)`` if given. ``rowmap`` runs the row-wise parts (link
    distances, the refinement's exact checks, the overlap graph's LPs); the result does not
    depend on it."""
    t0 = time.perf_counter()
    ws = build_grid(spec, progress, rowmap)
    t1 = time.perf_counter()
    res = build_region(ws, max_halfspaces=spec.max_halfspaces,
                       progress=stage_progress(progress, "region"))
    t2 = time.perf_counter()
    out = replace(ws, region=res.region, seconds=t2 - t0, region_seconds=t2 - t1,
                  region_info={**res.info(),
                               "max_halfspaces": float(spec.max_halfspaces)})
    if cover:
        rc = build_cover(out, progress=stage_progress(progress, "cover"), refined=refined_cover,
                         rowmap=rowmap)
        out = replace(out, cover=rc, seconds=time.perf_counter() - t0)
    if progress is not None:
        progress("done", 1.0)
    return out
