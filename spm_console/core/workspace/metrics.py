"""Figures of merit of one workspace, to compare wrist designs (paper Sec. VI-C compares SPM
structures by their workspace and conditioning).

From a built :class:`~spm_console.core.workspace.data.Workspace` (grid classified by
Algorithm 2, region P of eq. (30)):

- the feasible set's volume on the grid (nodes × Δ³, deg³) and its fraction of the θ box;
- P's volume (exact, from its vertices, deg³) and the fraction of feasible nodes inside it;
- the conditioning index ζ (eq. 16) over the feasible set: mean (a global conditioning
  index on the grid) and minimum;
- the smallest gap between the capsules of links of different legs over the feasible set,
  mm (distance − 2δ: ≥ 0 on feasible nodes by definition), and at home;
- the reachable orientation cone. Each feasible node's platform rotation R (from home) is
  split into tilt-and-torsion angles about the platform normal at home n⁰: tilt
  θt = ∠(n⁰, R n⁰), its azimuth φ about n⁰, and torsion σ. The cone is the smallest, over
  the azimuth sectors of :data:`AZIMUTH_SECTOR_DEG`, of the largest tilt a feasible node
  reaches in that sector (any torsion): a grid estimate of the half-angle the wrist can
  point within (one node per sector reaches it; that every smaller tilt is reachable too
  is not checked). The torsion range at zero tilt is max σ − min σ over the feasible nodes
  whose tilt is at most one grid step Δ.

Degrees and mm at the interface; radians inside.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.model import normal
from spm_console.core.workspace.data import Workspace

F = NDArray[np.float64]

#: Width of one azimuth sector of the orientation cone, deg (24 sectors).
AZIMUTH_SECTOR_DEG = 15.0


@dataclass(frozen=True)
class WorkspaceMetrics:
    """Figures of merit of one workspace (deg, deg³, mm)."""

    nodes: int
    """Grid nodes."""
    feasible_nodes: int
    """Home-connected feasible nodes."""
    feasible_volume_deg3: float
    """Feasible nodes × Δ³, deg³."""
    feasible_fraction: float
    """Feasible nodes / grid nodes."""
    p_volume_deg3: float
    """Volume of the region P, deg³."""
    p_halfspaces: int
    """Half-spaces of P."""
    p_coverage: float
    """Fraction of the feasible nodes inside P."""
    zeta_mean: float
    """Mean conditioning index ζ over the feasible nodes (NaN when there are none)."""
    zeta_min: float
    """Smallest ζ over the feasible nodes (NaN when there are none)."""
    clearance_min_mm: float
    """Smallest gap between capsules of links of different legs over the feasible nodes, mm."""
    clearance_home_mm: float
    """That gap at the home node, mm."""
    tilt_cone_deg: float
    """Largest platform tilt reached in every azimuth sector, deg."""
    torsion_min_deg: float
    """Smallest torsion of the feasible nodes at (near) zero tilt, deg."""
    torsion_max_deg: float
    """Largest torsion of the feasible nodes at (near) zero tilt, deg."""

    @property
    def torsion_range_deg(self) -> float:
        """Torsion (yaw) range at zero tilt, deg."""
        return self.torsion_max_deg - self.torsion_min_deg


def tilt_torsion_deg(R: F, n_home: F) -> tuple[F, F, F]:
    """(tilt, azimuth, torsion) in deg of rotations R (..., 3, 3) about the normal ``n_home``.

    In a frame H = [e1 e2 n⁰] (e1 ⊥ n⁰, fixed), Q = Hᵀ R H = Rz(φ) Ry(θt) Rz(σ − φ):
    θt = acos Q₂₂, φ = atan2(Q₁₂, Q₀₂), and σ = atan2(Q₁₀ − Q₀₁, Q₀₀ + Q₁₁) (exact for
    any θt < 180°, defined at θt = 0)."""
    n = np.asarray(n_home, float) / np.linalg.norm(n_home)
    seed = np.eye(3)[int(np.argmin(np.abs(n)))]
    e1 = seed - n * float(seed @ n)
    e1 /= np.linalg.norm(e1)
    H = np.stack([e1, np.cross(n, e1), n], axis=1)
    Q = (H.T @ R) @ H  # Hᵀ R H for every rotation
    tilt = np.degrees(np.arccos(np.clip(Q[..., 2, 2], -1.0, 1.0)))
    azimuth = np.degrees(np.arctan2(Q[..., 1, 2], Q[..., 0, 2]))
    torsion = np.degrees(np.arctan2(Q[..., 1, 0] - Q[..., 0, 1], Q[..., 0, 0] + Q[..., 1, 1]))
    return tilt, azimuth, torsion


def tilt_cone_deg(tilt: F, azimuth: F, sector_deg: float = AZIMUTH_SECTOR_DEG) -> float:
    """Largest tilt reached in every azimuth sector (0 when a sector is empty), deg."""
    sectors = round(360.0 / sector_deg)
    k = np.floor((np.asarray(azimuth) + 180.0) / sector_deg).astype(int) % sectors
    best = np.zeros(sectors)
    np.maximum.at(best, k, np.asarray(tilt, float))
    return float(best.min())


def workspace_metrics(ws: Workspace) -> WorkspaceMetrics:
    """The figures of merit of ``ws`` (see the module docstring). Needs the workspace's
    kinematic model (attached by a build)."""
    model, _ = ws.exact_models()
    feas = ws.feasible
    count = int(feas.sum())
    gap = ws.min_link_mm - ws.min_distance_mm
    n_home = normal(model.v_home)
    if count:
        zeta = ws.zeta[feas]
        tilt, az, tors = tilt_torsion_deg(ws.R[feas], n_home)
        near_zero = tilt <= ws.step_deg + 1e-9
        zero_tors = tors[near_zero] if near_zero.any() else np.zeros(1)
        zeta_mean, zeta_min = float(zeta.mean()), float(zeta.min())
        clearance = float(np.nanmin(gap[feas]))
        cone = tilt_cone_deg(tilt, az)
    else:
        zeta_mean = zeta_min = clearance = math.nan
        cone, zero_tors = 0.0, np.zeros(1)
    return WorkspaceMetrics(
        nodes=int(ws.klass.size), feasible_nodes=count,
        feasible_volume_deg3=count * ws.step_deg ** 3,
        feasible_fraction=count / max(int(ws.klass.size), 1),
        p_volume_deg3=ws.region.volume(), p_halfspaces=ws.region.halfspaces,
        p_coverage=ws.coverage(), zeta_mean=zeta_mean, zeta_min=zeta_min,
        clearance_min_mm=clearance, clearance_home_mm=float(gap[ws.home_index]),
        tilt_cone_deg=cone, torsion_min_deg=float(zero_tors.min()),
        torsion_max_deg=float(zero_tors.max()),
    )
