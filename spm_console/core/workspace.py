"""Workspace grid (paper Sec. IV, Algorithm 2): FK by flood fill, ζ, link distances, classes.

Every node of the θ grid (profile ``[workspace]``) is solved once by continuation
from home (:func:`~spm_console.core.fk_grid.track_grid`), then its conditioning
index ζ and its closest inter-leg link distance (closed-form segment distances,
chunked to bound memory) are computed. A node is *feasible* when ζ ≥ ζ_min, no
two links of different legs are closer than 2δ, and it is connected to the home
node through feasible nodes (6-connectivity: face neighbours only, the same
neighbourhood the FK flood fill uses). The convex region P is then built from the
grid (:mod:`spm_console.core.region_build`), and a cover of the feasible set by
several convex regions with their overlap graph (:mod:`spm_console.core.cover`).

Units: the dataclass exposes degrees and mm; radians stay inside.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import IntEnum
from functools import partial

import numpy as np
from numpy.typing import NDArray

from spm_console.core.certify import CertifiedSet
from spm_console.core.continuation import PATH_ZETA_FLOOR
from spm_console.core.cover import RegionCover
from spm_console.core.fk_grid import track_grid
from spm_console.core.kinematics import SpmModel, platform_axes
from spm_console.core.links import LinkModel
from spm_console.core.region import Region
from spm_console.core.rowmap import RowMap, serial
from spm_console.core.workspace_check import ThetaCheck, check_one

F = NDArray[np.float64]
B = NDArray[np.bool_]

#: Version of the workspace algorithm and its stored arrays (part of the cache key):
#: bump it whenever the grid, classification or region construction changes.
FORMAT_VERSION = 6
#: Nodes per chunk of the link-distance computation (bounds temporary memory).
LINK_CHUNK = 1024
#: Neighbourhood of the home-connectivity flood fill: 6 = face neighbours.
CONNECTIVITY = 6

#: progress(stage, fraction): stage is "fk", "links", "region", "cover" or "done"; fraction in [0, 1].
Progress = Callable[[str, float], None]


class NodeClass(IntEnum):
    """Class code of a grid node (``Workspace.klass``); the first that applies wins."""

    FEASIBLE = 0
    """ζ ≥ ζ_min, links apart, connected to home through feasible nodes."""
    SINGULAR = 1
    """ζ < ζ_min (links may also collide)."""
    COLLIDING = 2
    """ζ ≥ ζ_min but two links of different legs closer than 2δ."""
    UNREACHED = 3
    """The home-mode FK cannot be tracked there without crossing a singularity."""
    DISCONNECTED = 4
    """Pointwise feasible but cut off from home by infeasible nodes."""


@dataclass(frozen=True)
class Workspace:
    """The classified θ grid and the convex region P (θ in degrees, lengths in mm).

    Node arrays are indexed [i1, i2, i3] like ``axes_deg``.
    """

    axes_deg: tuple[F, F, F]
    """Grid values of θ1, θ2, θ3, deg."""
    step_deg: float
    """Grid spacing Δ, deg."""
    zeta: F
    """Conditioning index ζ per node (0 where unreached)."""
    min_link_mm: F
    """Closest distance between links of different legs, mm (NaN where unreached)."""
    closest_pair: NDArray[np.int16]
    """Index into ``LinkModel.pairs()`` of the closest pair (−1 where unreached)."""
    R: F
    """Solved platform rotation per node (M1, M2, M3, 3, 3); NaN where unreached."""
    klass: NDArray[np.uint8]
    """:class:`NodeClass` code per node."""
    region: Region
    """The convex region P = {θ : A θ ≤ b}, θ in degrees."""
    zeta_min: float
    """Singularity threshold used."""
    min_distance_mm: float
    """Collision threshold 2δ used, mm."""
    home_index: tuple[int, int, int]
    """Index of the grid node nearest the home configuration."""
    seconds: float
    """Wall time of the build (grid + region + cover), s."""
    region_seconds: float = 0.0
    """Wall time of the region construction alone, s."""
    region_info: dict[str, float] = field(default_factory=dict)
    """Diagnostics of the region construction (iterations, coverage, ...)."""
    cover: RegionCover | None = field(default=None, compare=False)
    """Convex regions covering the feasible set (``regions[0]`` is P) and their overlap
    graph; None when not built (:func:`build_grid`)."""
    model: SpmModel | None = field(default=None, compare=False, repr=False)
    """The kinematic model it was built from (for exact checks); not stored in the cache."""
    links: LinkModel | None = field(default=None, compare=False, repr=False)
    """The link model it was built from (for exact checks); not stored in the cache."""

    def exact_models(self) -> tuple[SpmModel, LinkModel]:
        """(kinematic model, link model) for exact checks; ValueError when not attached."""
        if self.model is None or self.links is None:
            raise ValueError("this workspace carries no kinematic/link model for exact checks")
        return self.model, self.links

    @property
    def shape(self) -> tuple[int, int, int]:
        return (len(self.axes_deg[0]), len(self.axes_deg[1]), len(self.axes_deg[2]))

    @property
    def reached(self) -> B:
        return np.asarray(self.klass != NodeClass.UNREACHED)

    @property
    def feasible(self) -> B:
        """Home-connected feasible nodes."""
        return np.asarray(self.klass == NodeClass.FEASIBLE)

    @property
    def singular(self) -> B:
        """ζ < ζ_min, or unreachable in the home mode (beyond a singularity)."""
        return np.asarray(~self.reached | (self.zeta < self.zeta_min))

    @property
    def colliding(self) -> B:
        """Links of different legs closer than 2δ (reached nodes only)."""
        with np.errstate(invalid="ignore"):
            return np.asarray(self.reached & (self.min_link_mm < self.min_distance_mm))

    def theta_deg(self) -> F:
        """All node θ as (M1, M2, M3, 3), deg."""
        return np.stack(np.meshgrid(*self.axes_deg, indexing="ij"), -1)

    def range_deg(self) -> tuple[float, float]:
        lo = min(float(a[0]) for a in self.axes_deg)
        hi = max(float(a[-1]) for a in self.axes_deg)
        return lo, hi

    def coverage(self) -> float:
        """Fraction of the feasible nodes that lie in P."""
        th = self.theta_deg()[self.feasible]
        if len(th) == 0:
            return 0.0
        return float(self.region.contains(th, tol=1e-7).mean())

    def counts(self) -> dict[str, int]:
        """Node counts; ``singular`` and ``colliding`` may overlap (a node can be both)."""
        k = self.klass
        return {
            "nodes": int(k.size),
            "feasible": int((k == NodeClass.FEASIBLE).sum()),
            "singular": int(self.singular.sum()),
            "colliding": int(self.colliding.sum()),
            "unreached": int((k == NodeClass.UNREACHED).sum()),
            "disconnected": int((k == NodeClass.DISCONNECTED).sum()),
        }

    def certified_set(self) -> CertifiedSet:
        """The grid's certified feasible set P′ (:mod:`spm_console.core.certify`)."""
        return CertifiedSet(self.feasible, np.array([a[0] for a in self.axes_deg], float),
                            float(self.step_deg))

    def index_of(self, theta_deg: F) -> tuple[int, int, int] | None:
        """Index of the grid node nearest θ (deg), or None outside the grid (by > Δ/2)."""
        idx = []
        for a, t in zip(self.axes_deg, np.asarray(theta_deg, float), strict=True):
            k = int(np.rint((t - a[0]) / self.step_deg))
            if k < 0 or k >= len(a) or abs(a[k] - t) > 0.5 * self.step_deg + 1e-9:
                return None
            idx.append(k)
        return (idx[0], idx[1], idx[2])


@dataclass(frozen=True)
class GridSpec:
    """What a workspace build needs (built from a profile by ``spm_console.models``)."""

    model: SpmModel
    links: LinkModel
    axes_deg: tuple[F, F, F]
    """Grid values of θ1, θ2, θ3, deg."""
    step_deg: float
    zeta_min: float
    max_halfspaces: int
    home_deg: F
    """Home θ, deg."""
    box_deg: tuple[float, float]
    """θ range of the grid box, deg."""


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


def _stage(progress: Progress | None, stage: str) -> Callable[[float], None] | None:
    if progress is None:
        return None
    return lambda f: progress(stage, f)


def build_grid(spec: GridSpec, progress: Progress | None = None,
               rowmap: RowMap = serial) -> Workspace:
    """Algorithm 2 over the grid, without the region (``region`` = the grid box). ``rowmap``
    runs the link distances (:mod:`spm_console.core.rowmap`)."""
    t0 = time.perf_counter()
    model, links = spec.model, spec.links
    axes_deg = spec.axes_deg
    axes = (np.radians(axes_deg[0]), np.radians(axes_deg[1]), np.radians(axes_deg[2]))
    g = track_grid(model, axes, zeta_floor=PATH_ZETA_FLOOR, progress=_stage(progress, "fk"))
    shape = g.shape
    reached = g.reached.ravel()
    th = g.theta().reshape(-1, 3)[reached]
    Rr = g.R.reshape(-1, 3, 3)[reached]
    links_progress = _stage(progress, "links")
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


def build_workspace(spec: GridSpec, progress: Progress | None = None,
                    cover: bool = True, refined_cover: bool = False,
                    rowmap: RowMap = serial) -> Workspace:
    """Grid (Algorithm 2) plus the convex region P and (``cover``) the region cover, refined
    near the boundary with ``refined_cover`` (:func:`~spm_console.core.cover.build_cover`);
    ``progress(stage, fraction)`` if given. ``rowmap`` runs the row-wise parts (link
    distances, the refinement's exact checks, the overlap graph's LPs); the result does not
    depend on it."""
    from dataclasses import replace

    from spm_console.core.cover import build_cover
    from spm_console.core.region_build import build_region

    t0 = time.perf_counter()
    ws = build_grid(spec, progress, rowmap)
    t1 = time.perf_counter()
    res = build_region(ws, max_halfspaces=spec.max_halfspaces,
                       progress=_stage(progress, "region"))
    t2 = time.perf_counter()
    out = replace(ws, region=res.region, seconds=t2 - t0, region_seconds=t2 - t1,
                  region_info={**res.info(),
                               "max_halfspaces": float(spec.max_halfspaces)})
    if cover:
        rc = build_cover(out, progress=_stage(progress, "cover"), refined=refined_cover,
                         rowmap=rowmap)
        out = replace(out, cover=rc, seconds=time.perf_counter() - t0)
    if progress is not None:
        progress("done", 1.0)
    return out


def check_theta(ws: Workspace, theta_deg: F) -> ThetaCheck:
    """Is θ (deg) feasible, and inside P? ``ws`` from ``workspace_cache.load_or_build``
    (or ``models.build_workspace``): it carries the models the exact check needs."""
    model, links = ws.exact_models()
    return check_one(ws, model, links, theta_deg)
