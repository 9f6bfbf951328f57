"""Workspace grid (paper Sec. IV, Algorithm 2): FK by flood fill, ζ, link distances, classes.

Every node of the θ grid (profile ``[workspace]``) is solved once by continuation
from home (:func:`~spm_console.core.kinematics.fk_grid.track_grid`), then its conditioning
index ζ and its closest inter-leg link distance (closed-form segment distances,
chunked to bound memory) are computed. A node is *feasible* when ζ ≥ ζ_min, no
two links of different legs are closer than 2δ, and it is connected to the home
node through feasible nodes (6-connectivity: face neighbours only, the same
neighbourhood the FK flood fill uses). The convex region P and the cover are built on
top of this grid (:mod:`spm_console.core.workspace_build`).

Units: the dataclass exposes degrees and mm; radians stay inside.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from functools import partial

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.continuation import PATH_ZETA_FLOOR
from spm_console.core.kinematics.fk_grid import track_grid
from spm_console.core.kinematics.links import LinkModel
from spm_console.core.kinematics.model import platform_axes
from spm_console.core.polytope.region import Region
from spm_console.core.workspace.check import ThetaCheck, check_one
from spm_console.core.workspace.data import GridSpec, NodeClass, Progress, Workspace
from spm_console.core.workspace.rowmap import RowMap, serial

F = NDArray[np.float64]
B = NDArray[np.bool_]

#: Nodes per chunk of the link-distance computation (bounds temporary memory).
LINK_CHUNK = 1024
#: Neighbourhood of the home-connectivity flood fill: 6 = face neighbours.
CONNECTIVITY = 6

def link_distances(
    links: LinkModel, u: F, w: F, v: F, chunk: int = LINK_CHUNK,
    progress: Callable[[float], None] | None = None,
) -> tuple[F, NDArray[np.int16]]:
    """Closest inter-leg link distance (mm) and pair index for (N, 3, 3) w, v, in chunks."""
    n = len(w)
    dmin = np.empty(n)
    arg = np.empty(n, np.int16)
    for s in range(0, n, chunk):
        d = links.pair_distances(u, w[s : s + chunk], v[s : s + chunk])
        dmin[s : s + chunk] = d.min(-1)
        arg[s : s + chunk] = d.argmin(-1)
        if progress is not None and (s // chunk) % 8 == 0:
            progress(min(1.0, (s + chunk) / max(n, 1)))
    return dmin, arg


def _link_rows(links: LinkModel, u: F, w: F, v: F,
               rows: NDArray[np.int64]) -> tuple[F, NDArray[np.int16]]:
    """:func:`link_distances` of the nodes ``rows`` (row-wise in ``rows``)."""
    return link_distances(links, u, w[rows], v[rows])


def home_connected(ok: B, home: tuple[int, int, int]) -> B:
    """Nodes of ``ok`` connected to ``home`` through ``ok`` nodes (6-connectivity)."""
    from scipy import ndimage  # here: ~0.4 s to import, and loading a cached workspace
    # never labels

    if not ok[home]:
        return np.zeros_like(ok)
    structure = ndimage.generate_binary_structure(3, 1)
    lab, _ = ndimage.label(ok, structure=structure)
    return np.asarray(lab == lab[home])


def classify(zeta: F, dmin: F, reached: B, zeta_min: float, dist_min: float,
             home: tuple[int, int, int]) -> NDArray[np.uint8]:
    """Class codes (:class:`NodeClass`) from ζ, link distances and reachability."""
    with np.errstate(invalid="ignore"):
        sing = reached & (zeta < zeta_min)
        coll = reached & ~sing & (dmin < dist_min)
    ok = reached & ~sing & ~coll
    conn = home_connected(ok, home)
    k = np.full(zeta.shape, NodeClass.DISCONNECTED, np.uint8)
    k[conn] = NodeClass.FEASIBLE
    k[sing] = NodeClass.SINGULAR
    k[coll] = NodeClass.COLLIDING
    k[~reached] = NodeClass.UNREACHED
    return k


def stage_progress(progress: Progress | None, stage: str) -> Callable[[float], None] | None:
    if progress is None:
        return None
    return lambda f: progress(stage, f)


def build_grid(spec: GridSpec, progress: Progress | None = None,
               rowmap: RowMap = serial) -> Workspace:
    """Algorithm 2 over the grid, without the region (``region`` = the grid box). ``rowmap``
    runs the link distances (:mod:`spm_console.core.workspace.rowmap`)."""
    t0 = time.perf_counter()
    model, links = spec.model, spec.links
    axes_deg = spec.axes_deg
    axes = (np.radians(axes_deg[0]), np.radians(axes_deg[1]), np.radians(axes_deg[2]))
    g = track_grid(model, axes, zeta_floor=PATH_ZETA_FLOOR, progress=stage_progress(progress, "fk"))
    shape = g.shape
    reached = g.reached.ravel()
    th = g.theta().reshape(-1, 3)[reached]
    Rr = g.R.reshape(-1, 3, 3)[reached]
    links_progress = stage_progress(progress, "links")
    if links_progress is not None:
        links_progress(0.0)
    w = model.geom.w(th)
    if links_progress is not None:
        links_progress(0.0)
    v = platform_axes(Rr, model.v_home)
    if rowmap is serial:
        d_r, k_r = link_distances(links, model.u, w, v, progress=links_progress)
    else:  # reported as one piece: the other half may run in another process (by index:
        # a forked helper has w and v already)
        d_r, k_r = rowmap(partial(_link_rows, links, model.u, w, v), np.arange(len(w)))
    dmin = np.full(reached.size, np.nan)
    dmin[reached] = d_r
    pair = np.full(reached.size, -1, np.int16)
    pair[reached] = k_r
    home = tuple(
        int(np.argmin(np.abs(a - t))) for a, t in zip(axes_deg, spec.home_deg, strict=True)
    )
    klass = classify(g.zeta, dmin.reshape(shape), g.reached, spec.zeta_min, 2.0 * links.delta,
                     (home[0], home[1], home[2]))
    lo, hi = spec.box_deg
    return Workspace(
        axes_deg=axes_deg, step_deg=spec.step_deg, zeta=g.zeta, min_link_mm=dmin.reshape(shape),
        closest_pair=pair.reshape(shape), R=g.R, klass=klass, region=Region.box(lo, hi),
        zeta_min=spec.zeta_min, min_distance_mm=2.0 * links.delta,
        home_index=(home[0], home[1], home[2]), seconds=time.perf_counter() - t0,
        model=model, links=links,
    )


def check_theta(ws: Workspace, theta_deg: F) -> ThetaCheck:
    """Is θ (deg) feasible, and inside P? ``ws`` from ``workspace_cache.load_or_build``
    (or ``models.build_workspace``): it carries the models the exact check needs."""
    model, links = ws.exact_models()
    return check_one(ws, model, links, theta_deg)
