"""Pointwise assessment of one pose: ζ, closest links, feasibility and the reason."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from spm_console.core.kinematics.links import LinkModel
from spm_console.core.kinematics.model import Pose, SpmModel


@dataclass(frozen=True)
class Assessment:
    """Is a solved pose usable, and if not, why."""

    zeta: float
    """Conditioning index ζ."""
    min_link_distance_mm: float
    """Closest distance between links of different legs, mm."""
    closest_pair: str
    """Which segments are closest, e.g. 'leg1 DE - leg2 EF'."""
    in_range: bool
    """θ lies inside the workspace grid range."""
    feasible: bool
    """ζ ≥ ζ_min, no link closer than 2δ, and θ inside the grid range."""
    reason: str
    """Why not feasible (empty when feasible)."""


def assess(
    model: SpmModel, links: LinkModel, pose: Pose, zeta_min: float,
    theta_range_deg: tuple[float, float],
) -> Assessment:
    """Check singularity (ζ < ζ_min), link interference (< 2δ) and the grid range."""
    w = model.geom.w(pose.theta)
    dmin, k = links.min_distance(model.u, w, pose.v)
    i, s1, j, s2 = links.pairs()[int(k)]
    pair = f"leg{i + 1} {s1} - leg{j + 1} {s2}"
    th = pose.theta_deg
    lo, hi = theta_range_deg
    in_range = bool(np.all(th >= lo - 1e-9) and np.all(th <= hi + 1e-9))
    reasons = []
    if pose.zeta < zeta_min:
        reasons.append(f"singular: ζ = {pose.zeta:.3f} < ζ_min = {zeta_min}")
    if float(dmin) < 2 * links.delta:
        reasons.append(
            f"links collide: {pair} at {float(dmin):.1f} mm < 2δ = {2 * links.delta:.1f} mm"
        )
    if not in_range:
        reasons.append(f"θ outside the workspace range [{lo}, {hi}]°")
    return Assessment(
        zeta=pose.zeta, min_link_distance_mm=float(dmin), closest_pair=pair,
        in_range=in_range, feasible=not reasons, reason="; ".join(reasons),
    )
