"""Unique FK of every θ connected to home: the straight path, else a path through the grid.

Unique FK (:mod:`spm_console.core.kinematics.model`) continues the home pose along the
straight segment from home to θ. That segment may cross a singularity although θ
is reachable from home around it. Then FK continues along a polyline through the
workspace grid instead:

1. The graph: grid nodes the workspace's flood fill tracked from home in the home
   assembly and working modes with ζ ≥ :data:`PATH_ZETA_FLOOR` (every node that is
   not ``UNREACHED``), joined to their face neighbours. ζ need not reach ζ_min and
   link collisions do not matter: FK is geometry, a colliding or ill-conditioned
   configuration still has its unique pose; feasibility is judged afterwards.
2. The route: a shortest path from home (edges weighted to keep away from low ζ)
   to a graph node near θ whose straight segment to θ continues, shortened by
   straight shortcuts that stay inside cells whose eight corners are graph nodes.
3. The pose is carried by continuation from home along every segment of that
   polyline, then to θ (a shortcut that fails falls back to its grid steps).

θ is refused only when no such route exists, with the reason: θ outside the grid
(the straight segment was the only attempt), or no assembly mode at θ on the home
side of every singularity (no path from home can reach it), or θ within the
continuation floor of a singularity, or no route at the grid's resolution.
Angles: radians inside, degrees in the reported waypoints.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.continuation import PATH_ZETA_FLOOR
from spm_console.core.kinematics.model import FkResult, SpmModel
from spm_console.core.kinematics.modes import solve_all
from spm_console.core.workspace.data import NodeClass, Workspace

F = NDArray[np.float64]
B = NDArray[np.bool_]
I3 = tuple[int, int, int]

#: Edge weight 1 + ZETA_WEIGHT / ζ (ζ the smaller of its two nodes): keeps routes off
#: near-singular nodes when a better-conditioned detour of similar length exists.
ZETA_WEIGHT = 0.05
#: Nodes tried as the last waypoint before θ (nearest first).
MAX_LAST_NODES = 16
#: Smallest |det J1| and |J2 diagonal entry| of a graph node: below it the node is taken to sit
#: on a singularity whatever its sign (ζ alone misses the poses where all three J2 entries
#: vanish together: ζ is invariant to their common scale).
SIDE_TOL = 1e-9
#: Agreement (max |ΔR|) between the pose carried along the route and the grid's own pose.
POSE_AGREEMENT = 1e-6


@dataclass(frozen=True)
class FkGraph:
    """Home-connected, non-singular grid nodes and their shortest-path tree from home."""

    axes_deg: tuple[F, F, F]
    """Grid values of θ1, θ2, θ3, deg."""
    step_deg: float
    """Grid spacing Δ, deg."""
    nodes: B
    """(M1, M2, M3): tracked from home in the home modes with ζ ≥ the continuation floor."""
    R: F
    """The flood fill's platform rotation per node (M1, M2, M3, 3, 3)."""
    home_index: I3
    """The node nearest home."""
    parent: NDArray[np.int64]
    """Flat index of each node's predecessor toward home (negative at home and off the graph)."""

    @property
    def shape(self) -> I3:
        return (len(self.axes_deg[0]), len(self.axes_deg[1]), len(self.axes_deg[2]))

    def node_deg(self, idx: I3) -> F:
        """θ of node ``idx``, deg."""
        return np.array([float(self.axes_deg[k][idx[k]]) for k in range(3)])

    def inside(self, theta_deg: F) -> bool:
        """θ (deg) within the grid box (so a cell of the grid holds it)."""
        return all(a[0] - 1e-9 <= t <= a[-1] + 1e-9
                   for a, t in zip(self.axes_deg, np.asarray(theta_deg, float), strict=True))

    def node_path(self, idx: I3) -> list[I3]:
        """Nodes from home to ``idx`` along the tree (empty when ``idx`` is off the graph)."""
        if not self.nodes[idx]:
            return []
        home = int(np.ravel_multi_index(self.home_index, self.shape))
        k = int(np.ravel_multi_index(idx, self.shape))
        out = [k]
        while k != home:
            k = int(self.parent[k])
            if k < 0:
                return []
            out.append(k)
        return [_i3(np.unravel_index(j, self.shape)) for j in reversed(out)]

    def clear(self, a_deg: F, b_deg: F) -> bool:
        """The straight segment a→b (deg) stays in cells (or on cell faces) whose corners
        are all graph nodes."""
        d = np.asarray(b_deg, float) - np.asarray(a_deg, float)
        n = max(2, math.ceil(4.0 * float(np.abs(d).max()) / self.step_deg) + 1)
        pts = np.asarray(a_deg, float) + np.linspace(0.0, 1.0, n)[:, None] * d
        lo = np.array([a[0] for a in self.axes_deg])
        m = np.array(self.shape)
        x = (pts - lo) / self.step_deg
        c = np.floor(x + 1e-9).astype(int)
        if (c < 0).any() or (c > m - 1).any():
            return False
        off_plane = (x - c) > 1e-9  # on a grid plane the segment touches only that face
        for corner in np.ndindex(2, 2, 2):
            k = np.minimum(c + np.asarray(corner) * off_plane, m - 1)
            if not self.nodes[k[:, 0], k[:, 1], k[:, 2]].all():
                return False
        return True

    def last_nodes(self, theta_deg: F) -> list[I3]:
        """Graph nodes of the 4×4×4 block around θ (deg), nearest first (≤ MAX_LAST_NODES)."""
        lo = np.array([a[0] for a in self.axes_deg])
        m = np.array(self.shape)
        c = np.floor((np.asarray(theta_deg, float) - lo) / self.step_deg).astype(int)
        cand: list[tuple[float, I3]] = []
        for off in np.ndindex(4, 4, 4):
            k = c + np.asarray(off) - 1
            if (k < 0).any() or (k >= m).any():
                continue
            idx = _i3(k)
            if self.nodes[idx]:
                cand.append((float(np.linalg.norm(self.node_deg(idx) - theta_deg)), idx))
        cand.sort()
        return [idx for _, idx in cand[:MAX_LAST_NODES]]


def _i3(k: object) -> I3:
    a = [int(x) for x in k]  # type: ignore[attr-defined]
    return (a[0], a[1], a[2])


def home_side(model: SpmModel, theta_rad: F, R: F) -> NDArray[np.bool_]:
    """Poses (batched) strictly on the home's side of every singularity: det J1 and each
    J2 diagonal entry with the home's sign and magnitude above :data:`SIDE_TOL`."""
    _, d1, d2 = model.mode_check(theta_rad, R)
    return np.asarray((d1 > SIDE_TOL) & (d2 > SIDE_TOL).all(-1))


def fk_graph(ws: Workspace, model: SpmModel) -> FkGraph:
    """The FK graph of a workspace: every node its flood fill reached (any ζ ≥ the floor,
    colliding or not) strictly on the home's side of the singularities, face-neighbour
    edges, and the shortest-path tree from home."""
    nodes = np.asarray((ws.klass != NodeClass.UNREACHED) & (ws.zeta >= PATH_ZETA_FLOOR))
    th = np.radians(np.stack(np.meshgrid(*ws.axes_deg, indexing="ij"), -1)[nodes])
    nodes[nodes] = home_side(model, th, ws.R[nodes])
    return graph_of(ws.axes_deg, float(ws.step_deg), nodes, ws.zeta, ws.R, ws.home_index)


def graph_of(axes_deg: tuple[F, F, F], step_deg: float, nodes: B, zeta: F, R: F,
             home_index: I3) -> FkGraph:
    """The graph on ``nodes`` (M1, M2, M3) with edge weights from ``zeta`` and the
    shortest-path tree from ``home_index``."""
    shape = nodes.shape
    from scipy.sparse import coo_matrix  # here: ~0.3 s to import, not before the first screen
    from scipy.sparse.csgraph import dijkstra

    n = nodes.size
    flat = np.arange(n).reshape(shape)
    z = np.where(nodes, zeta, 0.0)
    rows, cols, wts = [], [], []
    for ax in range(3):
        a = [slice(None)] * 3
        b = [slice(None)] * 3
        a[ax], b[ax] = slice(0, -1), slice(1, None)
        both = nodes[tuple(a)] & nodes[tuple(b)]
        zmin = np.minimum(z[tuple(a)], z[tuple(b)])[both]
        rows.append(flat[tuple(a)][both])
        cols.append(flat[tuple(b)][both])
        wts.append(1.0 + ZETA_WEIGHT / np.maximum(zmin, PATH_ZETA_FLOOR))
    r, c, w = np.concatenate(rows), np.concatenate(cols), np.concatenate(wts)
    g = coo_matrix((np.concatenate([w, w]), (np.concatenate([r, c]), np.concatenate([c, r]))),
                   shape=(n, n)).tocsr()
    home = int(np.ravel_multi_index(home_index, shape))
    parent = np.full(n, -9999, np.int64)
    if nodes[home_index]:
        _, pred = dijkstra(g, directed=False, indices=home, return_predecessors=True)
        parent = np.asarray(pred, np.int64)
    return FkGraph(axes_deg=axes_deg, step_deg=step_deg, nodes=nodes, R=R,
                   home_index=home_index, parent=parent)


@dataclass(frozen=True)
class _Leg:
    ok: bool
    R: F
    steps: int
    min_zeta: float
    reason: str


def _segment(model: SpmModel, a_deg: F, R: F, b_deg: F) -> _Leg:
    r = model.track(np.radians(b_deg), np.radians(a_deg), R)
    if not r.ok or r.pose is None:
        return _Leg(False, R, r.steps, r.path_min_zeta, r.reason)
    return _Leg(True, r.pose.R, r.steps, r.path_min_zeta, "")


def _shortcuts(graph: FkGraph, pts: list[F]) -> list[int]:
    """Indices into ``pts`` of a shortened polyline (greedy: advance while clear)."""
    keep = [0]
    i = 0
    while i < len(pts) - 1:
        j = i + 1
        while j + 1 < len(pts) and graph.clear(pts[i], pts[j + 1]):
            j += 1
        keep.append(j)
        i = j
    return keep


def _follow(model: SpmModel, graph: FkGraph, pts: list[F]) -> tuple[_Leg, list[F]]:
    """Carry the home pose along ``pts`` (deg, pts[0] = home θ), shortcuts first."""
    keep = _shortcuts(graph, pts)
    R = np.eye(3)
    steps, minz = 0, 1.0
    taken: list[F] = [pts[0]]
    for i, j in itertools.pairwise(keep):
        leg = _segment(model, pts[i], R, pts[j])
        sub = [j] if leg.ok else list(range(i + 1, j + 1))
        if not leg.ok:
            leg = _Leg(True, R, 0, 1.0, "")
            for k in sub:
                leg2 = _segment(model, pts[k - 1], leg.R, pts[k])
                if not leg2.ok:
                    return leg2, taken
                leg = _Leg(True, leg2.R, leg.steps + leg2.steps, min(leg.min_zeta, leg2.min_zeta), "")
        R, steps, minz = leg.R, steps + leg.steps, min(minz, leg.min_zeta)
        taken += [pts[k] for k in sub]
    return _Leg(True, R, steps, minz, ""), taken


def _dedupe(pts: list[F]) -> tuple[tuple[float, ...], ...]:
    """Waypoints (deg) without consecutive repeats."""
    out: list[tuple[float, ...]] = []
    for p in pts:
        if not out or max(abs(a - b) for a, b in zip(out[-1], p, strict=True)) > 1e-12:
            out.append(_pt(p))
    return tuple(out)


def _outside(lo: float, hi: float, straight_reason: str) -> str:
    return (f"outside the workspace grid ({lo:g}..{hi:g}° per joint), so no path through it "
            f"exists; the straight line from home was the only attempt: {straight_reason}")


def _pt(theta_deg: F) -> tuple[float, ...]:
    """A waypoint, deg, rounded to 1e-9° (no radian round-trip noise in the report)."""
    return tuple(round(float(x), 9) for x in theta_deg)


def route_fk(model: SpmModel, graph: FkGraph, theta_rad: F, straight: FkResult) -> FkResult:
    """FK of θ (rad) around a singularity through ``graph``, after the ``straight``
    attempt failed; refuses θ not connected to home, with the reason."""
    th_deg = np.degrees(np.asarray(theta_rad, float))
    if not graph.inside(th_deg):
        lo, hi = graph.axes_deg[0][0], graph.axes_deg[0][-1]
        return replace(straight, reason=_outside(float(lo), float(hi), straight.reason))
    home_deg = np.degrees(model.theta_home)
    for last in graph.last_nodes(th_deg):
        # cheap test first: does the grid's pose at this node continue straight to θ?
        if not _segment(model, graph.node_deg(last), graph.R[last], th_deg).ok:
            continue
        pts = [home_deg] + [graph.node_deg(k) for k in graph.node_path(last)]
        leg, taken = _follow(model, graph, pts)
        if not leg.ok or float(np.abs(leg.R - graph.R[last]).max()) > POSE_AGREEMENT:
            continue
        end = _segment(model, graph.node_deg(last), leg.R, th_deg)
        if not end.ok:
            continue
        pose = model.pose(np.asarray(theta_rad, float), end.R)
        return FkResult(ok=True, pose=pose, reason="", path_min_zeta=min(leg.min_zeta, end.min_zeta),
                        steps=leg.steps + end.steps,
                        waypoints_deg=_dedupe([*taken, th_deg]), route="graph")
    return replace(straight, reason=_not_connected(model, graph, theta_rad, straight.reason))


def _not_connected(model: SpmModel, graph: FkGraph, theta_rad: F, straight_reason: str) -> str:
    """Why no route reached θ (rad), from every assembly mode at θ (multi-start solve)."""

    th = np.asarray(theta_rad, float)
    Rs = solve_all(model.geom, th, model.v_home)
    head = "not connected to home through non-singular configurations"
    TH = np.broadcast_to(th, (len(Rs), 3))
    side = home_side(model, TH, np.asarray(Rs)) if Rs else np.zeros(0, bool)
    if not side.any():
        return (f"{head}: no assembly mode at this θ lies strictly on the home's side of the "
                "singularities (sign of det J1, the legs' working modes), so every path from "
                "home crosses one (ζ = 0)")
    z = float(np.max(model.mode_check(TH, np.asarray(Rs))[0][side]))
    if z < PATH_ZETA_FLOOR:
        return (f"{head}: θ lies within the continuation floor of a singularity (ζ = {z:.1e} "
                f"< {PATH_ZETA_FLOOR:g} in the home's modes); FK is not tracked that close")
    return (f"{head} at the grid's resolution (Δ = {graph.step_deg:g}°): no home-connected "
            f"node near θ continues to it without crossing a singularity; straight line from "
            f"home: {straight_reason}")


def fk_connected(
    model: SpmModel,
    theta_rad: F,
    graph: Callable[[], FkGraph],
    grid_box_deg: tuple[float, float] | None = None,
    start: FkResult | None = None,
) -> FkResult:
    """Unique FK of θ (rad) with the path taken: straight from home (or from ``start``, a
    solved pose of this function), else through the workspace graph from home.

    ``graph()`` is called only when the straight path fails and θ lies in ``grid_box_deg``
    (deg, the same range for every joint; None: not known), so the common case never
    loads a workspace. Refused results say why (``reason``).
    """
    th = np.asarray(theta_rad, float)
    home_deg = np.degrees(model.theta_home)
    end = _pt(np.degrees(th))
    if start is not None and start.ok and start.pose is not None:
        r = model.track(th, start.pose.theta, start.pose.R)
        if r.ok:
            prefix = start.waypoints_deg or (_pt(start.pose.theta_deg),)
            return replace(r, waypoints_deg=(*prefix, end), route=start.route)
    r = model.track(th)
    if r.ok:
        return replace(r, waypoints_deg=(_pt(home_deg), end), route="straight")
    if grid_box_deg is not None and not all(
            grid_box_deg[0] - 1e-9 <= t <= grid_box_deg[1] + 1e-9 for t in end):
        return replace(r, reason=_outside(grid_box_deg[0], grid_box_deg[1], r.reason))
    return route_fk(model, graph(), th, r)
