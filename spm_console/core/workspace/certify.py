"""The certified feasible set of a workspace grid, and pointwise membership in it.

The grid certifies a configuration θ when every grid node n with |n − θ|∞ < h is a
home-connected feasible node and lies on the grid (so θ is inside the grid box). With
h = Δ (the grid step) this is exactly the paper's P′ on the grid: the complement of the
open cubes of half-width Δ around every node that is not feasible — the set every region
(P, and every region grown for a plan) is built inside, and the set the workspace
verifier samples. A smaller h (Δ − margin, kept above Δ/2 so that every point has a node
within h on each axis) is a looser test for measured positions near the boundary.

Near the boundary the same criterion is applied at a finer resolution, on demand
(:mod:`spm_console.core.workspace.refine`, :class:`~spm_console.core.workspace.refine.RefinedCertifiedSet`);
:func:`nodes_near` serves both lattices.

Membership costs a floor and at most 8 table look-ups per point, whatever the grid size:
it is the check the runtime applies to every sample of a plan and to the continuous motion
between samples before anything moves. Angles in degrees.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

F = NDArray[np.float64]
B = NDArray[np.bool_]

#: A point within this fraction of a grid step of a grid plane is on it (floating-point
#: round-off, e.g. a settling motion ending 1e-10° past the grid's edge at its goal).
ON_PLANE_TOL = 1e-9


@dataclass(frozen=True)
class CertifiedSet:
    """The feasible-node table of a grid (θ in degrees)."""

    feasible: B
    """(M1, M2, M3) home-connected feasible nodes."""
    origin_deg: F
    """(3,) θ of node [0, 0, 0], deg."""
    step_deg: float
    """Grid step Δ, deg."""

    @property
    def empty(self) -> bool:
        return not bool(self.feasible.any())

    def contains(self, theta_deg: F, half_width_deg: float | None = None) -> B:
        """Which points (…, 3) are certified (see module docstring); ``half_width_deg``
        defaults to Δ (the grid definition of P′) and must lie in (Δ/2, Δ]."""
        h = self.step_deg if half_width_deg is None else float(half_width_deg)
        if not 0.5 * self.step_deg < h <= self.step_deg:
            raise ValueError(f"half width {h} must lie in ({0.5 * self.step_deg}, {self.step_deg}]")
        th = np.asarray(theta_deg, float)
        near = nodes_near(th.reshape(-1, 3), self.origin_deg, self.step_deg,
                          self.feasible.shape, h / self.step_deg)
        idx = np.clip(near.index, 0, np.array(self.feasible.shape) - 1)
        hit = self.feasible[idx[..., 0], idx[..., 1], idx[..., 2]]
        return near.all_hold(hit).reshape(th.shape[:-1])


@dataclass(frozen=True)
class NearNodes:
    """The lattice nodes within L∞ distance < r·step of each point (at most 8 per point)."""

    finite: B
    """(n,) the point has finite coordinates."""
    index: NDArray[np.int64]
    """(n, 8, 3) integer index of the 8 corners of the point's cell (may lie off the lattice)."""
    needed: B
    """(n, 8) the corner is within the distance (its verdict matters)."""
    inside: B
    """(n, 8) the corner lies on the lattice."""

    def all_hold(self, verdict: B) -> B:
        """(n,) every needed corner is on the lattice and ``verdict`` (n, 8) holds there."""
        return np.asarray(self.finite & np.all(~self.needed | (self.inside & verdict), axis=1))


def nodes_near(pts: F, origin: F, step: float, shape: tuple[int, ...], ratio: float) -> NearNodes:
    """:class:`NearNodes` of ``pts`` (n, 3) on the lattice origin + step·index of ``shape``:
    per axis, corner lo qualifies when frac < ratio, corner lo + 1 when 1 − frac < ratio."""
    ok = np.all(np.isfinite(pts), axis=1)
    u = (np.where(np.isfinite(pts), pts, 0.0) - origin) / step
    near = np.rint(u)  # on a lattice plane up to round-off (1e-9 of a step): on it
    u = np.where(np.abs(u - near) <= ON_PLANE_TOL, near, u)
    lo = np.floor(u)
    frac = u - lo
    want = (frac < ratio, (1.0 - frac) < ratio)
    offs = np.array([[(c >> 2) & 1, (c >> 1) & 1, c & 1] for c in range(8)])
    idx = lo.astype(np.int64)[:, None, :] + offs[None]
    needed = np.all(np.where(offs[None] == 1, want[1][:, None, :], want[0][:, None, :]), axis=2)
    inside = np.all((idx >= 0) & (idx < np.array(shape)), axis=2)
    return NearNodes(ok, idx, needed, inside)
