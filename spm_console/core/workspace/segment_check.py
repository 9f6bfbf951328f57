"""Is the straight segment between two configurations inside the feasible set P'?

Two checks, both must pass:
1. on the grid: the segment stays in the grid box and never enters the open cube
   of half-width Δ around a node that is not home-connected feasible (the grid
   definition of P', exact slab test) — or, refined near the boundary, the open cubes
   of a mixed set (:class:`CubeSet`: half-width Δ around grid nodes, h = Δ/4 around
   fine nodes; :mod:`spm_console.core.regions.refined`);
2. exactly: samples every ≤ Δ/4 along it pass FK by continuation, ζ ≥ ζ_min and
   link distances ≥ 2δ.
A failure raises :class:`InfeasibleError` naming the first θ where it happens
and why. Angles in degrees.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from spm_console.core.workspace.check import PointChecks, check_points, pair_name
from spm_console.errors import InfeasibleError, Issue

if TYPE_CHECKING:
    from spm_console.core.workspace.data import Workspace

F = NDArray[np.float64]


def _fmt(t: F) -> str:
    return "[" + ", ".join(f"{x:.2f}" for x in t) + "]"


def segment_entry(a: F, b: F, centers: F, half: float) -> tuple[F, F]:
    """Entry parameter t ∈ [0, 1] of the segment a→b into each open cube (∞ if it
    misses), by the slab method; also returns the exit parameter."""
    d = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (centers - half - a) / d
        t2 = (centers + half - a) / d
    tmin = np.minimum(t1, t2)
    tmax = np.maximum(t1, t2)
    # zero direction component: inside the open slab for all t, or never
    flat = d == 0
    inside_flat = np.abs(a - centers) < half
    tmin = np.where(flat, np.where(inside_flat, -np.inf, np.inf), tmin)
    tmax = np.where(flat, np.where(inside_flat, np.inf, -np.inf), tmax)
    t_in = np.maximum(tmin.max(-1), 0.0)
    t_out = np.minimum(tmax.min(-1), 1.0)
    hit = t_in < t_out - 1e-12
    return np.where(hit, t_in, np.inf), np.where(hit, t_out, -np.inf)


def node_reason(ws: Workspace, flat: int) -> str:
    """Why a grid node is not feasible, in words."""
    from spm_console.core.workspace.data import NodeClass

    _, links = ws.exact_models()
    idx = np.unravel_index(flat, ws.shape)
    th = ws.theta_deg()[idx]
    k = NodeClass(int(ws.klass[idx]))
    if k == NodeClass.UNREACHED:
        why = "unreachable in the home assembly mode (beyond a singularity)"
    elif k == NodeClass.SINGULAR:
        why = f"singular (ζ = {float(ws.zeta[idx]):.3f} < ζ_min = {ws.zeta_min:g})"
    elif k == NodeClass.COLLIDING:
        why = (f"colliding ({pair_name(links, int(ws.closest_pair[idx]))} at "
               f"{float(ws.min_link_mm[idx]):.1f} mm < 2δ = {ws.min_distance_mm:.1f} mm)")
    else:
        why = "cut off from home by infeasible nodes"
    return f"grid node {_fmt(th)}° is {why}"


@dataclass(frozen=True)
class CubeSet:
    """Open cubes a feasible segment must not enter: centres (n, 3) deg, one half-width."""

    centres_deg: F
    half_deg: float
    label: str
    """How the half-width reads in a refusal, e.g. "Δ = 2°"."""
    describe: Callable[[int], str]
    """Why the node at row j is not feasible, in words."""


def grid_cubes(ws: Workspace) -> CubeSet:
    """The cubes of half-width Δ around every grid node that is not home-connected feasible."""
    bad = np.flatnonzero(ws.klass.ravel() != 0)
    th = ws.theta_deg().reshape(-1, 3)[bad]
    return CubeSet(th, float(ws.step_deg), f"Δ = {ws.step_deg:g}°",
                   lambda j: node_reason(ws, int(bad[j])))


@dataclass(frozen=True)
class ExactSamples:
    """The exact checks of points every ≤ Δ/4 along a segment (deg)."""

    points: F
    checks: PointChecks
    ok: NDArray[np.bool_]

    @property
    def feasible(self) -> bool:
        return bool(self.ok.all())

    def summary(self) -> str:
        return (f"min ζ = {self.checks.zeta.min():.3f}, closest links "
                f"{np.nanmin(self.checks.min_link_mm):.1f} mm")


def check_range(ws: Workspace, a: F, b: F) -> None:
    """Raise :class:`InfeasibleError` unless both ends lie in the grid box."""
    lo, hi = ws.range_deg()
    for name, t in (("first", a), ("second", b)):
        if not np.all((t >= lo - 1e-9) & (t <= hi + 1e-9)):
            raise InfeasibleError(
                f"the {name} configuration {_fmt(t)}° is outside the workspace grid "
                f"[{lo:g}, {hi:g}]°"
            )


def exact_samples(ws: Workspace, a: F, b: F) -> ExactSamples:
    """Exact checks every ≤ Δ/4 along a→b (deg), both ends included."""
    model, links = ws.exact_models()
    n = max(2, int(np.ceil(np.abs(b - a).max() / (0.25 * ws.step_deg))) + 1)
    pts = a + (b - a) * np.linspace(0.0, 1.0, n)[:, None]
    pc = check_points(ws, model, links, pts)
    return ExactSamples(pts, pc, pc.pointwise_ok(ws.zeta_min, ws.min_distance_mm))


#: What a refusal adds when the segment is exactly feasible but within Δ of an infeasible node.
GRID_HINT = ("a finer workspace grid (smaller workspace.step_deg) may hold a convex region "
             "containing both")


def check_segment(ws: Workspace, a: F, b: F, cubes: Sequence[CubeSet] | None = None,
                  samples: ExactSamples | None = None, hint: str = GRID_HINT) -> None:
    """Raise :class:`InfeasibleError` unless the straight segment a→b (deg) is feasible:
    in the grid box, outside every cube of ``cubes`` (default: :func:`grid_cubes`, the
    grid definition of P′) and feasible at the exact samples (``samples`` if already
    computed)."""
    _, links = ws.exact_models()
    check_range(ws, a, b)
    sets = [grid_cubes(ws)] if cubes is None else list(cubes)
    ex = exact_samples(ws, a, b) if samples is None else samples
    first: tuple[float, CubeSet, int] | None = None
    for cs in sets:
        t_in, _ = segment_entry(a, b, cs.centres_deg, cs.half_deg)
        if np.isfinite(t_in).any():
            j = int(np.argmin(t_in))
            if first is None or float(t_in[j]) < first[0]:
                first = (float(t_in[j]), cs, j)
    if first is not None:
        t, cs, j = first
        where = a + (b - a) * t
        at = ("from its first configuration" if t <= 1e-12
              else f"at θ ≈ {_fmt(where)}°")
        msg = (f"the straight segment {_fmt(a)}° → {_fmt(b)}° leaves the feasible set {at}: "
               f"within {cs.label} of " + cs.describe(j))
        if ex.feasible:
            msg += f". Checked exactly, the segment itself is feasible ({ex.summary()}): {hint}"
        raise InfeasibleError(msg, Issue.END_NOT_FEASIBLE)
    if not ex.feasible:
        k = int(np.argmin(ex.ok))
        why = ex.checks.reason(k, ws.zeta_min, ws.min_distance_mm, links)
        raise InfeasibleError(
            f"the straight segment {_fmt(a)}° → {_fmt(b)}° is infeasible at "
            f"θ = {_fmt(ex.points[k])}°: {why}", Issue.END_NOT_FEASIBLE
        )
