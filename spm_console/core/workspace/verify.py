"""Sampling verifier of the region P: uniform points inside P, each checked exactly.

Points are drawn uniformly in the grid box and kept when inside P (P ⊆ box, so
the accepted points are uniform in P). Each is checked by FK continuation from
the nearest solved grid node (whose pose was tracked from home), ζ ≥ ζ_min and
all inter-leg link distances ≥ 2δ. Angles in degrees, lengths in mm.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.links import LinkModel
from spm_console.core.kinematics.model import SpmModel
from spm_console.core.polytope.region import Region
from spm_console.core.workspace.check import check_points, pair_name
from spm_console.core.workspace.data import Workspace

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


#: Most box points drawn at once (the membership test holds one float per face and point).
DRAW_MAX = 250_000
#: Points checked per call of check_points.
CHUNK = 20_000


def iter_region_samples(region: Region, lo: float, hi: float, n: int,
                        rng: np.random.Generator) -> Iterator[F]:
    """n points uniform inside ``region`` ∩ [lo, hi]³ by rejection from the box, deg, in
    batches (memory bounded by DRAW_MAX, whatever n)."""
    got = 0
    first = True
    while got < n:
        pts = rng.uniform(lo, hi, size=(min(max(2 * (n - got), 1024), DRAW_MAX), 3))
        keep = pts[region.contains(pts, tol=0.0)]
        if len(keep) == 0 and first and region.chebyshev()[1] <= 0:
            raise ValueError("the region is empty")
        first = False
        keep = keep[: n - got]
        got += len(keep)
        if len(keep):
            yield keep


def sample_region(region: Region, lo: float, hi: float, n: int, rng: np.random.Generator) -> F:
    """n points uniform inside ``region`` ∩ [lo, hi]³ by rejection from the box, deg."""
    return np.concatenate([np.zeros((0, 3)), *iter_region_samples(region, lo, hi, n, rng)])


def _chunks(batches: Iterator[F], size: int) -> Iterator[F]:
    """The points of ``batches`` regrouped into arrays of ``size`` rows (the last shorter)."""
    buf: list[F] = []
    held = 0
    for b in batches:
        buf.append(b)
        held += len(b)
        while held >= size:
            allp = np.concatenate(buf)
            yield allp[:size]
            buf, held = [allp[size:]], held - size
    if held:
        yield np.concatenate(buf)


@dataclass
class _Tally:
    """Running totals over the checked chunks (nothing per sample is kept)."""

    infeasible: int = 0
    fk_failures: int = 0
    singular: int = 0
    colliding: int = 0
    min_zeta: float = np.inf
    min_link: float = np.inf
    min_pair: int = -1
    worst: float = -np.inf
    worst_theta: F | None = None


def verify_region(
    ws: Workspace, model: SpmModel, links: LinkModel, region: Region | None = None,
    n: int = 100_000, seed: int = 0, progress: Callable[[float], None] | None = None,
) -> VerifyReport:
    """Check ``n`` uniform samples of ``region`` (default: the workspace's P) exactly."""
    t0 = time.perf_counter()
    reg = ws.region if region is None else region
    lo, hi = ws.range_deg()
    batches = iter_region_samples(reg, lo, hi, n, np.random.default_rng(seed))
    t = _Tally()
    done = 0
    for pts in _chunks(batches, CHUNK):
        pc = check_points(ws, model, links, pts)
        z, d, fk = pc.zeta, pc.min_link_mm, pc.fk_ok
        ok = pc.pointwise_ok(ws.zeta_min, ws.min_distance_mm)
        t.infeasible += int((~ok).sum())
        t.fk_failures += int((~fk).sum())
        t.singular += int((fk & (z < ws.zeta_min)).sum())
        t.colliding += int((fk & (d < ws.min_distance_mm)).sum())
        if fk.any():
            t.min_zeta = min(t.min_zeta, float(z[fk].min()))
            dd = np.where(fk, d, np.inf)
            dd = np.where(np.isnan(dd), np.inf, dd)
            k = int(np.argmin(dd))
            if dd[k] < t.min_link:
                t.min_link, t.min_pair = float(dd[k]), int(pc.closest_pair[k])
        with np.errstate(invalid="ignore"):
            viol = np.maximum(1.0 - z / ws.zeta_min,
                              1.0 - np.nan_to_num(d, nan=0.0) / ws.min_distance_mm)
        viol = np.where(fk, viol, np.inf)
        k = int(np.argmax(viol))
        if t.worst_theta is None or viol[k] > t.worst:
            t.worst, t.worst_theta = float(viol[k]), pts[k].copy()
        done += len(pts)
        if progress is not None:
            progress(min(1.0, done / n))
    found = bool(np.isfinite(t.min_zeta))
    return VerifyReport(
        samples=n, infeasible=t.infeasible, fk_failures=t.fk_failures, singular=t.singular,
        colliding=t.colliding, min_zeta=float(t.min_zeta) if found else 0.0,
        min_link_mm=t.min_link if found else float("nan"),
        min_link_pair=pair_name(links, t.min_pair) if found else "",
        worst_theta_deg=[] if t.worst_theta is None else [float(x) for x in t.worst_theta],
        worst_violation=t.worst, seconds=time.perf_counter() - t0,
    )


def verify_cover(
    ws: Workspace, model: SpmModel, links: LinkModel, n: int = 100_000, seed: int = 0,
    progress: Callable[[float], None] | None = None,
) -> list[VerifyReport]:
    """:func:`verify_region` on every region of the workspace's cover (``n`` samples each,
    region k drawn with seed ``seed + k``); ValueError when the workspace has no cover."""
    if ws.cover is None:
        raise ValueError("this workspace has no region cover")
    regs = ws.cover.regions
    out = []
    for k, reg in enumerate(regs):
        sub = None if progress is None else (
            lambda f, k=k: progress((k + f) / len(regs)))
        out.append(verify_region(ws, model, links, region=reg, n=n, seed=seed + k,
                                 progress=sub))
    return out
