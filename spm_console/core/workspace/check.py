"""Exact pointwise checks against a built workspace: FK by continuation from the
nearest solved grid node, ζ, link distances, grid range, home connectivity, P.

Continuation from a grid node (its pose was itself tracked from home by the flood
fill) to a point within the node's cell is a short predictor-corrector path; it is
refused, like :meth:`SpmModel.track`, when det J1 or a J2 diagonal entry changes
sign or ζ drops below the path floor. Angles in degrees at the interface.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.component_ops import Mat, as_array
from spm_console.core.kinematics.continuation import Kernel, Local, from_mat, to_mat, to_vec
from spm_console.core.kinematics.jacobian import conditioning_index
from spm_console.core.kinematics.links import LinkModel
from spm_console.core.kinematics.model import SpmModel, platform_axes

if TYPE_CHECKING:
    from spm_console.core.workspace.data import Workspace

F = NDArray[np.float64]
B = NDArray[np.bool_]

#: Largest continuation step from a grid node, rad.
STEP_RAD = np.radians(0.5)
#: Points per chunk in batched checks (bounds memory).
CHUNK = 20_000


def track_from(model: SpmModel, th0: F, R0: F, th1: F, steps: int) -> tuple[F, B]:
    """Vectorized continuation, row k from (th0[k], R0[k]) to th1[k] (rad) in ``steps``
    equal steps. Returns (R (n, 3, 3), ok (n,)); ok is False where the corrector
    failed or the path left the home assembly/working modes."""
    R0 = np.array(R0, float)
    ok = np.isfinite(R0).all((-2, -1))
    R0[~ok] = np.eye(3)
    kern = Kernel(model)
    a, b = to_vec(th0), to_vec(th1)
    R: Mat = to_mat(R0)
    th = a
    at: Local | None = None
    for k in range(1, steps + 1):
        th_new = [a[i] + (b[i] - a[i]) * (k / steps) for i in range(3)]
        st = kern.step(th, R, th_new, at)
        R, at = st.R, st.at
        ok &= st.good()
        th = th_new
    return from_mat(R), np.asarray(ok, bool)


def own_steps(ws: Workspace, theta_deg: F) -> NDArray[np.int64]:
    """(n,) continuation steps of each point from its start node (:func:`check_points`'s
    choice): as few as keep every step ≤ :data:`STEP_RAD` in every joint. A function of the
    point alone, so its verdict does not depend on the points checked with it."""
    th_deg = np.atleast_2d(np.asarray(theta_deg, float))
    return _steps_from(ws, th_deg, _start_nodes(ws, th_deg)[0])


def _steps_from(ws: Workspace, th_deg: F, node: NDArray[np.int64]) -> NDArray[np.int64]:
    span = np.abs(np.radians(th_deg) - np.radians(ws.theta_deg().reshape(-1, 3)[node])).max(-1)
    return np.maximum(1, np.ceil(span / STEP_RAD - 1e-9)).astype(np.int64)


def exact_ok(ws: Workspace, model: SpmModel, links: LinkModel, theta_deg: F,
             steps: int | None = None) -> B:
    """(n,) the verdict ``pointwise_ok & start_feasible`` of :func:`check_points` with
    ``steps`` continuation steps per point (default :func:`own_steps`), computed only as far
    as needed: rows outside the box or without a home-connected feasible start node are
    refused at once, a row is dropped at the first step that fails, and link distances are
    computed only where ζ ≥ ζ_min."""
    th_deg = np.atleast_2d(np.asarray(theta_deg, float))
    out = np.zeros(len(th_deg), bool)
    lo, hi = ws.range_deg()
    in_range = np.all((th_deg >= lo - 1e-9) & (th_deg <= hi + 1e-9), -1)
    node, feas = _start_nodes(ws, th_deg)
    count = _steps_from(ws, th_deg, node) if steps is None else np.full(len(th_deg), int(steps))
    kern = Kernel(model)
    R_nodes = ws.R.reshape(-1, 3, 3)
    node_th = np.radians(ws.theta_deg().reshape(-1, 3))
    go = in_range & feas
    for n_steps in np.unique(count[go]):
        todo = np.flatnonzero(go & (count == n_steps))
        for s in range(0, len(todo), CHUNK):
            rows = todo[s:s + CHUNK]
            out[rows] = _track_and_check(ws, kern, links, node_th[node[rows]],
                                         R_nodes[node[rows]], np.radians(th_deg[rows]),
                                         int(n_steps))
    return out


def _track_and_check(ws: Workspace, kern: Kernel, links: LinkModel, th0: F, R0: F, th1: F,
                     steps: int) -> B:
    """Continue rows from (th0, R0) to th1 (rad) in ``steps`` steps, then ζ and the links."""
    out = np.zeros(len(th0), bool)
    rows = np.arange(len(th0))
    a, b = to_vec(th0), to_vec(th1)
    R = to_mat(R0)
    th = a
    z = np.zeros(len(rows))
    at: Local | None = None
    for k in range(1, steps + 1):
        th_new = [a[i] + (b[i] - a[i]) * (k / steps) for i in range(3)]
        st = kern.step(th, R, th_new, at)
        keep = np.flatnonzero(st.good())
        rows, z, at = rows[keep], as_array(st.zeta)[keep], st.at.take(keep)
        a, b = [x[keep] for x in a], [x[keep] for x in b]
        th = [as_array(x)[keep] for x in th_new]
        R = [[as_array(x)[keep] for x in row] for row in st.R]
    sing = np.flatnonzero(z >= ws.zeta_min)
    R = [[x[sing] for x in row] for row in R]
    w = [[as_array(x)[sing] for x in wi] for wi in at.w] if at is not None else []
    v = [[as_array(x) for x in vi] for vi in kern.axes(R)]
    out[rows[sing]] = links.apart(np.asarray(kern.u), w, v, ws.min_distance_mm)
    return out


@dataclass(frozen=True)
class PointChecks:
    """Exact checks of many θ (arrays of length n)."""

    theta_deg: F
    in_range: B
    """Inside the grid box."""
    start_feasible: B
    """The node the continuation started from is home-connected feasible."""
    fk_ok: B
    """FK tracked to θ in the home modes."""
    R: F
    """Solved rotations (n, 3, 3) (meaningful where fk_ok)."""
    zeta: F
    """ζ (0 where FK failed)."""
    min_link_mm: F
    """Closest inter-leg link distance, mm (NaN where FK failed)."""
    closest_pair: NDArray[np.int64]
    """Index into LinkModel.pairs() (−1 where FK failed)."""

    def reason(self, k: int, zeta_min: float, dist_min: float, links: LinkModel) -> str:
        """Why point ``k`` fails the exact checks, in words (FK, then ζ, then links)."""
        if not self.fk_ok[k]:
            return "FK cannot be continued there in the home assembly mode"
        if self.zeta[k] < zeta_min:
            return f"singular (ζ = {self.zeta[k]:.3f} < ζ_min = {zeta_min:g})"
        return (f"links collide ({pair_name(links, int(self.closest_pair[k]))} at "
                f"{self.min_link_mm[k]:.1f} mm < 2δ = {dist_min:.1f} mm)")

    def pointwise_ok(self, zeta_min: float, dist_min: float) -> B:
        with np.errstate(invalid="ignore"):
            return np.asarray(
                self.in_range & self.fk_ok & (self.zeta >= zeta_min)
                & (self.min_link_mm >= dist_min)
            )


def _start_nodes(ws: Workspace, th_deg: F) -> tuple[NDArray[np.int64], B]:
    """Flat index of the grid node to continue from for each θ, and whether it is
    home-connected feasible. Preference: feasible corners of θ's cell (nearest
    first), then any reached corner, then the nearest node."""
    shape = ws.shape
    a0 = np.array([a[0] for a in ws.axes_deg])
    rel = (th_deg - a0) / ws.step_deg
    base = np.floor(rel).astype(np.int64)
    frac = rel - base
    klass = ws.klass.ravel()
    best = np.full(len(th_deg), -1, np.int64)
    score = np.full(len(th_deg), np.inf)
    for corner in range(8):
        off = np.array([(corner >> i) & 1 for i in range(3)])
        idx = np.clip(base + off, 0, np.array(shape) - 1)
        flat = np.ravel_multi_index(idx.T, shape)
        dist = np.abs(frac - off).sum(-1)
        k = klass[flat]
        pen = np.where(k == 0, 0.0, np.where(np.isfinite(ws.R.reshape(-1, 9)[flat]).all(-1), 10.0,
                                             np.inf))
        s = dist + pen
        better = s < score
        best[better], score[better] = flat[better], s[better]
    fallback = ~np.isfinite(score)
    if fallback.any():
        near = np.clip(np.rint(rel[fallback]).astype(np.int64), 0, np.array(shape) - 1)
        best[fallback] = np.ravel_multi_index(near.T, shape)
    feas = klass[best] == 0
    return best, np.asarray(feas)


def check_points(ws: Workspace, model: SpmModel, links: LinkModel, theta_deg: F,
                 steps: int | None = None) -> PointChecks:
    """Exact checks of θ (n, 3) deg, continuation from the nearest solved grid node.

    ``steps``: continuation steps per point (default: enough for the farthest point of each
    chunk, ≤ :data:`STEP_RAD` each). A fixed count makes each point's verdict independent of
    the other points checked with it (the refined certification memoizes verdicts)."""
    th_deg = np.atleast_2d(np.asarray(theta_deg, float))
    n = len(th_deg)
    lo, hi = ws.range_deg()
    in_range = np.all((th_deg >= lo - 1e-9) & (th_deg <= hi + 1e-9), -1)
    node, feas = _start_nodes(ws, th_deg)
    R_nodes = ws.R.reshape(-1, 3, 3)
    node_th = np.radians(ws.theta_deg().reshape(-1, 3)[node])
    th = np.radians(th_deg)
    R_all = np.empty((n, 3, 3))
    ok_all = np.zeros(n, bool)
    for s in range(0, n, CHUNK):
        sl = slice(s, s + CHUNK)
        span = float(np.abs(th[sl] - node_th[sl]).max()) if n else 0.0
        n_steps = max(1, int(np.ceil(span / STEP_RAD))) if steps is None else int(steps)
        R, ok = track_from(model, node_th[sl], R_nodes[node[sl]], th[sl], n_steps)
        R_all[sl], ok_all[sl] = R, ok
    # poses from home for rows whose start node was unreached
    for k in np.flatnonzero(~np.isfinite(R_nodes[node]).all((-2, -1))):
        r = model.track(th[k])
        ok_all[k] = r.ok
        if r.pose is not None:
            R_all[k] = r.pose.R
    w = model.geom.w(th)
    v = platform_axes(R_all, model.v_home)
    zeta = np.where(ok_all, conditioning_index(model.u, v, w), 0.0)
    dmin = np.full(n, np.nan)
    pair = np.full(n, -1, np.int64)
    idx = np.flatnonzero(ok_all)
    for s in range(0, len(idx), 1024):
        sel = idx[s : s + 1024]
        d = links.pair_distances(model.u, w[sel], v[sel])
        dmin[sel] = d.min(-1)
        pair[sel] = d.argmin(-1)
    return PointChecks(th_deg, in_range, feas, ok_all, R_all, zeta, dmin, pair)


def pair_name(links: LinkModel, k: int) -> str:
    i, s1, j, s2 = links.pairs()[int(k)]
    return f"leg{i + 1} {s1} - leg{j + 1} {s2}"


@dataclass(frozen=True)
class ThetaCheck:
    """Is one configuration usable, and if not, why (θ in degrees, mm)."""

    theta_deg: F
    feasible: bool
    """In the grid range, FK tracked in the home modes, ζ ≥ ζ_min, links ≥ 2δ apart,
    and continued from a home-connected feasible grid node."""
    in_region: bool
    """Inside the cached convex region P."""
    reason: str
    """Why not feasible / not in P (empty when both hold)."""
    zeta: float | None
    min_link_mm: float | None
    closest_pair: str
    in_range: bool
    connected: bool
    region_slack_deg: float
    """Smallest b − Aθ over P's (unit-norm) rows: negative outside P, deg."""
    v: F | None
    """Top axes v1..v3 (rows) when FK succeeded."""

    @property
    def plannable(self) -> bool:
        """A plan can start or end here: feasible. Inside P the planner uses P; outside it,
        a route through the workspace's region cover (with a small region grown around an
        end that no cover region holds), else one region grown around the segment
        (``run.plan_request.plan_motion``, in that order)."""
        return self.feasible

    @property
    def verdict(self) -> str:
        """The one wording of this check (console, CLI and JSON)."""
        if not self.feasible:
            return f"NOT feasible: {self.reason}"
        if self.in_region:
            return "feasible, inside P: plannable in P"
        return (f"feasible, outside P by {-self.region_slack_deg:.2f}°: plannable through the "
                "region cover or a region grown around the segment")


def check_one(ws: Workspace, model: SpmModel, links: LinkModel, theta_deg: F) -> ThetaCheck:
    """Check one θ (deg) against the workspace and its region P."""
    th = np.asarray(theta_deg, float).reshape(3)
    pc = check_points(ws, model, links, th[None])
    zmin, dlim = ws.zeta_min, ws.min_distance_mm
    lo, hi = ws.range_deg()
    reasons = []
    fk_ok = bool(pc.fk_ok[0])
    z = float(pc.zeta[0]) if fk_ok else None
    d = float(pc.min_link_mm[0]) if fk_ok else None
    pair = pair_name(links, int(pc.closest_pair[0])) if fk_ok else ""
    if not bool(pc.in_range[0]):
        reasons.append(f"outside the workspace grid [{lo:g}, {hi:g}]°")
    if not fk_ok:
        reasons.append("no FK solution in the home assembly mode reachable without crossing "
                       "a singularity")
    else:
        assert z is not None and d is not None
        if z < zmin:
            reasons.append(f"singular: ζ = {z:.3f} < ζ_min = {zmin:g}")
        if d < dlim:
            reasons.append(f"links collide: {pair} at {d:.1f} mm < 2δ = {dlim:.1f} mm")
    point_ok = not reasons
    connected = bool(pc.start_feasible[0])
    if point_ok and not connected:
        reasons.append("not connected to home through feasible grid nodes")
    slack = float(ws.region.normalized().slack(th).min())
    in_region = slack >= -1e-9
    if not in_region:
        reasons.append(f"outside the region P by {-slack:.2f}°")
    v = platform_axes(pc.R[0], model.v_home) if fk_ok else None
    return ThetaCheck(
        theta_deg=th, feasible=point_ok and connected, in_region=in_region,
        reason="; ".join(reasons), zeta=z, min_link_mm=d, closest_pair=pair,
        in_range=bool(pc.in_range[0]), connected=connected, region_slack_deg=slack, v=v,
    )
