"""Is the straight segment between two configurations inside the feasible set P'?

Two checks, both must pass:
1. on the grid: the segment stays in the grid box and never enters the open cube
   of half-width Δ around a node that is not home-connected feasible (the grid
   definition of P', exact slab test);
2. exactly: samples every ≤ Δ/4 along it pass FK by continuation, ζ ≥ ζ_min and
   link distances ≥ 2δ.
A failure raises :class:`InfeasibleError` naming the first θ where it happens
and why. Angles in degrees.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from spm_console.core.workspace_check import check_points, pair_name
from spm_console.errors import InfeasibleError

if TYPE_CHECKING:
    from spm_console.core.workspace import Workspace

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
    from spm_console.core.workspace import NodeClass

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


def check_segment(ws: Workspace, a: F, b: F) -> None:
    """Raise :class:`InfeasibleError` unless the straight segment a→b (deg) is feasible."""
    model, links = ws.exact_models()
    lo, hi = ws.range_deg()
    for name, t in (("first", a), ("second", b)):
        if not np.all((t >= lo - 1e-9) & (t <= hi + 1e-9)):
            raise InfeasibleError(
                f"the {name} configuration {_fmt(t)}° is outside the workspace grid "
                f"[{lo:g}, {hi:g}]°"
            )
    th = ws.theta_deg().reshape(-1, 3)
    bad = np.flatnonzero(ws.klass.ravel() != 0)
    t_in, _ = segment_entry(a, b, th[bad], ws.step_deg)
    n = max(2, int(np.ceil(np.abs(b - a).max() / (0.25 * ws.step_deg))) + 1)
    pts = a + (b - a) * np.linspace(0.0, 1.0, n)[:, None]
    pc = check_points(ws, model, links, pts)
    ok = pc.pointwise_ok(ws.zeta_min, ws.min_distance_mm)
    if np.isfinite(t_in).any():
        j = int(np.argmin(t_in))
        where = a + (b - a) * float(t_in[j])
        msg = (f"the straight segment {_fmt(a)}° → {_fmt(b)}° leaves the feasible set at "
               f"θ ≈ {_fmt(where)}°: within Δ = {ws.step_deg:g}° of "
               + node_reason(ws, int(bad[j])))
        if ok.all():
            msg += (f". Checked exactly, the segment itself is feasible (min ζ = "
                    f"{pc.zeta.min():.3f}, closest links {np.nanmin(pc.min_link_mm):.1f} mm): "
                    f"a finer workspace grid (smaller workspace.step_deg, e.g. 1°) can hold a "
                    f"convex region containing both")
        raise InfeasibleError(msg)
    if not ok.all():
        k = int(np.argmin(ok))
        why = pc.reason(k, ws.zeta_min, ws.min_distance_mm, links)
        raise InfeasibleError(
            f"the straight segment {_fmt(a)}° → {_fmt(b)}° is infeasible at "
            f"θ = {_fmt(pts[k])}°: {why}"
        )
