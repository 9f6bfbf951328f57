"""Sampling verifier of the region P: uniform points inside P, each checked exactly.

Points are drawn uniformly in the grid box and kept when inside P (P ⊆ box, so
the accepted points are uniform in P). Each is checked by FK continuation from
the nearest solved grid node (whose pose was tracked from home), ζ ≥ ζ_min and
all inter-leg link distances ≥ 2δ. Angles in degrees, lengths in mm.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics import SpmModel
from spm_console.core.links import LinkModel
from spm_console.core.region import Region
from spm_console.core.workspace import Workspace
from spm_console.core.workspace_check import check_points, pair_name

F = NDArray[np.float64]


@dataclass(frozen=True)
class VerifyReport:
    """Outcome of :func:`verify_region`."""

    samples: int
    infeasible: int
    """Samples that fail any exact check."""
    fk_failures: int
    """Samples where FK could not be continued in the home modes."""
    singular: int
    """Samples with ζ < ζ_min."""
    colliding: int
    """Samples with links closer than 2δ."""
    min_zeta: float
    """Smallest ζ over the samples."""
    min_link_mm: float
    """Smallest inter-leg link distance over the samples, mm."""
    min_link_pair: str
    worst_theta_deg: list[float]
    """The sample with the worst relative violation (or the closest to one)."""
    worst_violation: float
    """max(1 − ζ/ζ_min, 1 − d/2δ) at the worst sample (≤ 0 means every sample passed)."""
    seconds: float

    @property
    def fraction_infeasible(self) -> float:
        return self.infeasible / self.samples if self.samples else 0.0


def sample_region(region: Region, lo: float, hi: float, n: int, rng: np.random.Generator) -> F:
    """n points uniform inside ``region`` ∩ [lo, hi]³ by rejection from the box, deg."""
    out: list[F] = []
    got = 0
    while got < n:
        pts = rng.uniform(lo, hi, size=(max(2 * (n - got), 1024), 3))
        keep = pts[region.contains(pts, tol=0.0)]
        if len(keep) == 0 and not out and region.chebyshev()[1] <= 0:
            raise ValueError("the region is empty")
        out.append(keep)
        got += len(keep)
    return np.concatenate(out)[:n]


def verify_region(
    ws: Workspace, model: SpmModel, links: LinkModel, region: Region | None = None,
    n: int = 100_000, seed: int = 0, progress: Callable[[float], None] | None = None,
) -> VerifyReport:
    """Check ``n`` uniform samples of ``region`` (default: the workspace's P) exactly."""
    t0 = time.perf_counter()
    reg = ws.region if region is None else region
    lo, hi = ws.range_deg()
    pts = sample_region(reg, lo, hi, n, np.random.default_rng(seed))
    zs, ds, oks, fks, pairs = [], [], [], [], []
    chunk = 20_000
    for s in range(0, n, chunk):
        pc = check_points(ws, model, links, pts[s : s + chunk])
        zs.append(pc.zeta)
        ds.append(pc.min_link_mm)
        fks.append(pc.fk_ok)
        oks.append(pc.pointwise_ok(ws.zeta_min, ws.min_distance_mm))
        pairs.append(pc.closest_pair)
        if progress is not None:
            progress(min(1.0, (s + chunk) / n))
    z = np.concatenate(zs)
    d = np.concatenate(ds)
    ok = np.concatenate(oks)
    fk = np.concatenate(fks)
    pr = np.concatenate(pairs)
    with np.errstate(invalid="ignore"):
        viol = np.maximum(1.0 - z / ws.zeta_min, 1.0 - np.nan_to_num(d, nan=0.0) / ws.min_distance_mm)
    viol = np.where(fk, viol, np.inf)
    k = int(np.argmax(viol))
    dk = int(np.nanargmin(np.where(fk, d, np.inf)))
    return VerifyReport(
        samples=n, infeasible=int((~ok).sum()), fk_failures=int((~fk).sum()),
        singular=int((fk & (z < ws.zeta_min)).sum()),
        colliding=int((fk & (d < ws.min_distance_mm)).sum()),
        min_zeta=float(z[fk].min()) if fk.any() else 0.0,
        min_link_mm=float(d[dk]) if fk.any() else float("nan"),
        min_link_pair=pair_name(links, int(pr[dk])) if fk.any() else "",
        worst_theta_deg=[float(x) for x in pts[k]], worst_violation=float(viol[k]),
        seconds=time.perf_counter() - t0,
    )
