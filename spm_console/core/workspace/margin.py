"""How far joint angles are from the edge of the grid's certified set P′.

P′ is the grid box less the open cubes of half-width Δ about every node that is not a
home-connected feasible node (:mod:`spm_console.core.workspace.certify`). Its complement is
those cubes and the outside of the box, so the L∞ distance from a point of P′ to its edge is

    min( min over such nodes n of ‖θ − n‖∞ − Δ ,  min over axes of the distance to the box ),

exact, and the same expression is minus the depth past the edge for a point outside. One
k-d tree query (L∞) per point. Angles in degrees.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from spm_console.core.workspace.certify import CertifiedSet

F = NDArray[np.float64]


def certified_margin_deg(cert: CertifiedSet, theta_deg: F) -> F:
    """The signed L∞ distance (…,) deg of each θ (…, 3) to the edge of ``cert``'s P′:
    positive inside, negative outside (see the module docstring); NaN for a non-finite θ."""
    from scipy.spatial import cKDTree  # ~0.2 s to import: only where a margin is asked for

    th = np.asarray(theta_deg, float)
    pts = th.reshape(-1, 3)
    shape = np.array(cert.feasible.shape)
    lo = np.asarray(cert.origin_deg, float)
    hi = lo + (shape - 1) * cert.step_deg
    box = np.minimum(pts - lo, hi - pts).min(axis=1)
    out = box.copy()
    blocked = np.argwhere(~cert.feasible)
    finite = np.isfinite(pts).all(axis=1)
    if len(blocked) and finite.any():
        tree = cKDTree(lo + blocked * cert.step_deg)
        d, _ = tree.query(pts[finite], p=np.inf)
        out[finite] = np.minimum(box[finite], d - cert.step_deg)
    out[~finite] = np.nan
    return out.reshape(th.shape[:-1])
