"""The workspace's data: the classified θ grid, the region P and its cover (θ in degrees,
lengths in mm), and what a build needs. Built by :mod:`spm_console.core.workspace.build`; every
module that reads a workspace imports it from here."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from enum import IntEnum
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.links import LinkModel
from spm_console.core.kinematics.model import SpmModel
from spm_console.core.polytope.cover import RegionCover
from spm_console.core.polytope.region import Region
from spm_console.core.workspace.certify import CertifiedSet

F = NDArray[np.float64]
B = NDArray[np.bool_]

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
        """Fraction of the feasible nodes that lie in P (computed once per workspace: the console
        shows it on every visit of its workspace step)."""
        return self._p_coverage

    @cached_property
    def _p_coverage(self) -> float:
        th = self.theta_deg()[self.feasible]
        if len(th) == 0:
            return 0.0
        return float(self.region.contains(th).mean())

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
        """The grid's certified feasible set P′ (:mod:`spm_console.core.workspace.certify`)."""
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
    """What a workspace build needs (built from a profile by ``spm_console.config.models``)."""

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
