"""A plan's route through several convex regions, and which samples each region binds.

A plan through one region keeps every sample k = 0..N (and the motion between samples)
in it. A plan across regions R₀, R₁, …, R_m switches at samples 0 < k₁ < … < k_m < N:
interval j (from sample j to j + 1) belongs to region R_i when k_i ≤ j < k_{i+1} (with
k₀ = 0, k_{m+1} = N), so the samples k₁…k_m lie in two consecutive regions at once (the
switch happens inside their overlap) and, both regions being convex, the straight path
between two samples of one interval stays in that interval's region. Angles in degrees.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.polytope.region import Region

F = NDArray[np.float64]
I = NDArray[np.int64]
B = NDArray[np.bool_]


@dataclass(frozen=True)
class RegionRoute:
    """Regions in the order the motion visits them and the samples where it switches."""

    regions: tuple[Region, ...]
    """R₀ … R_m, θ in degrees."""
    switch: tuple[int, ...]
    """k₁ < … < k_m: sample k_i lies in R_{i−1} and R_i (empty for one region)."""
    labels: tuple[str, ...] = ()
    """What each region is (e.g. "P", "cover region 7"); shown only."""

    def __post_init__(self) -> None:
        if not self.regions:
            raise ValueError("a route needs at least one region")
        if len(self.switch) != len(self.regions) - 1:
            raise ValueError(f"{len(self.regions)} regions need {len(self.regions) - 1} switch "
                             f"samples, got {len(self.switch)}")
        if any(b <= a for a, b in itertools.pairwise(self.switch)):
            raise ValueError(f"switch samples must increase strictly, got {list(self.switch)}")
        if self.labels and len(self.labels) != len(self.regions):
            raise ValueError("one label per region")

    @classmethod
    def single(cls, region: Region, label: str = "") -> RegionRoute:
        return cls((region,), (), (label,) if label else ())

    @property
    def count(self) -> int:
        return len(self.regions)

    def fits(self, N: int) -> bool:
        """Whether the switch samples lie strictly inside 0..N."""
        return all(0 < k < N for k in self.switch)

    def interval_region(self, N: int) -> I:
        """Region index of every interval j = 0..N−1."""
        j = np.arange(N)
        return np.searchsorted(np.asarray(self.switch, np.int64), j, side="right").astype(np.int64)

    def sample_mask(self, N: int) -> B:
        """(N+1, m+1): which regions bind sample k (both neighbours' at a switch)."""
        iv = self.interval_region(N)
        mask = np.zeros((N + 1, self.count), bool)
        mask[np.arange(N), iv] = True
        mask[np.arange(1, N + 1), iv] = True
        return mask

    def interval_mask(self, N: int) -> B:
        """(N, m+1): which region binds the motion inside interval j."""
        mask = np.zeros((N, self.count), bool)
        mask[np.arange(N), self.interval_region(N)] = True
        return mask

    def stacked(self) -> tuple[F, F, I]:
        """All rows (A (n, 3), b (n,)) and the region index of each row."""
        A = np.vstack([r.A for r in self.regions])
        b = np.concatenate([r.b for r in self.regions])
        owner = np.repeat(np.arange(self.count), [r.halfspaces for r in self.regions])
        return np.asarray(A, float), np.asarray(b, float), owner.astype(np.int64)

    def rescaled(self, N_old: int, N_new: int) -> RegionRoute:
        """The same regions with the switch samples moved in proportion to N_new / N_old
        (kept strictly increasing inside 1..N_new−1 when there is room)."""
        if not self.switch:
            return self
        return RegionRoute(self.regions, spread([k / N_old for k in self.switch], N_new),
                           self.labels)

    def violation_deg(self, theta_deg: F, mask: B) -> F:
        """Distance outside the binding regions, deg, per point of (n, 3) with mask (n, m+1):
        the worst over the regions that bind the point (0 inside all of them)."""
        pts = np.asarray(theta_deg, float).reshape(-1, 3)
        out = np.zeros(len(pts))
        for i, r in enumerate(self.regions):
            sel = mask[:, i]
            if sel.any():
                out[sel] = np.maximum(out[sel], r.violation_deg(pts[sel]))
        return out

    def describe(self) -> str:
        if self.count == 1:
            return "one region"
        names = self.labels or tuple(f"region {i}" for i in range(self.count))
        at = ", ".join(str(k) for k in self.switch)
        return (f"{self.count} regions ({' → '.join(names)}), switching at "
                f"sample{'s' if len(self.switch) > 1 else ''} {at}")


def spread(fractions: Sequence[float], N: int) -> tuple[int, ...]:
    """Switch samples at the given fractions of N, strictly increasing inside 1..N−1
    (pushed apart by one sample where rounding makes two meet). Needs N > len(fractions)."""
    m = len(fractions)
    if m >= N:
        raise ValueError(f"{m} switches need N > {m}, got N = {N}")
    ks = [min(max(round(f * N), 1), N - 1) for f in fractions]
    for i in range(m):  # forward: strictly increasing, leaving room for the rest
        lo = ks[i - 1] + 1 if i else 1
        ks[i] = min(max(ks[i], lo), N - (m - i))
    return tuple(ks)
