"""The record of one FK result (the keys of ``spm-console fk --json``), shared by the
CLI and the operator runtime, and FK with its path (straight from home, else through the
workspace grid). Angles in degrees, lengths in mm."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from spm_console.config.schema import Profile
from spm_console.core.kinematics.assess import assess
from spm_console.core.kinematics.links import LinkModel
from spm_console.core.kinematics.model import FkResult, SpmModel
from spm_console.core.kinematics.modes import AssemblyMode
from spm_console.core.workspace.data import Workspace
from spm_console.core.workspace.fk_path import FkGraph, fk_connected, fk_graph

F = NDArray[np.float64]

#: Waypoints shown in full in the human path line (longer paths are elided in the middle).
SHOWN_WAYPOINTS = 6


class FkGraphSource:
    """The FK graph of the profile's workspace, made on first need only: from the session's
    loaded workspace when there is one (``current()``), else from the cache (built when
    missing). Called only when a straight path from home failed."""

    def __init__(self, profile: Profile, model: SpmModel, cache_dir: Path | None = None,
                 current: Callable[[], Workspace | None] | None = None) -> None:
        self.profile, self.model, self.cache_dir, self.current = profile, model, cache_dir, current
        self._ws: Workspace | None = None
        self._graph: tuple[Workspace, FkGraph] | None = None

    def __call__(self) -> FkGraph:
        ws = self.current() if self.current is not None else None
        if ws is None:
            if self._ws is None:
                from spm_console.store.workspace_cache import load_or_build

                self._ws, _ = load_or_build(self.profile, self.cache_dir)
            ws = self._ws
        if self._graph is None or self._graph[0] is not ws:
            self._graph = (ws, fk_graph(ws, self.model))
        return self._graph[1]


def fk_route(profile: Profile, model: SpmModel, theta_deg: ArrayLike, graph: Callable[[], FkGraph],
             start: FkResult | None = None) -> FkResult:
    """Unique FK of θ (deg) with its path: straight from home (or ``start``), else through
    the workspace grid (``graph()`` called only then, and only for θ inside the grid)."""
    w = profile.workspace
    return fk_connected(model, np.radians(np.asarray(theta_deg, float)), graph,
                        (float(w.theta_min_deg), float(w.theta_max_deg)), start)


@dataclass(frozen=True)
class FkPath:
    """How FK reached θ: the polyline followed from home (or a known pose), deg."""

    route: str
    """"straight" (one segment) or "graph" (around a singularity through the workspace grid)."""
    waypoints_deg: tuple[tuple[float, ...], ...]
    """Corners of the polyline, both ends included, deg."""

    @property
    def waypoints(self) -> int:
        return len(self.waypoints_deg)

    def as_json(self) -> dict[str, object]:
        """The ``path`` key: route, waypoints (count), waypoints_deg."""
        return {"route": self.route, "waypoints": self.waypoints,
                "waypoints_deg": [list(p) for p in self.waypoints_deg]}

    def line(self) -> str:
        """One human line (long paths elided in the middle)."""
        pts = ["[" + ", ".join(f"{x:.2f}" for x in w) + "]" for w in self.waypoints_deg]
        if self.route == "straight" and self.waypoints == 2:
            return f"path     = straight line from home {pts[0]}°"
        if len(pts) > SHOWN_WAYPOINTS:
            pts = [*pts[:3], "…", *pts[-2:]]
        how = ("through the workspace grid (around a singularity)" if self.route == "graph"
               else "via a known pose")
        return f"path     = {self.waypoints} waypoints {how}: " + " → ".join(pts) + "°"


def fk_path(r: FkResult) -> FkPath | None:
    """The path of an FK result (None when it has no waypoints)."""
    return FkPath(r.route, r.waypoints_deg) if r.waypoints_deg else None


@dataclass(frozen=True)
class FkRecord:
    """One solved FK and its quality (the keys of ``spm-console fk --json``). Degrees, mm."""

    theta_deg: F
    v: F
    """Top axes v1..v3 as rows (3, 3)."""
    n: F
    """Platform normal (3,)."""
    zeta: float
    residual: float
    min_link_distance_mm: float
    closest_pair: str
    feasible: bool
    reason: str
    """Why not feasible (empty when feasible)."""
    path_min_zeta: float
    path: FkPath | None = None
    modes: tuple[AssemblyMode, ...] | None = None
    """Every assembly mode at θ, when asked for."""

    def as_json(self) -> dict[str, object]:
        """The ``fk --json`` record: these keys in this order after ``"ok": true``."""
        rec: dict[str, Any] = {
            "ok": True,
            "theta_deg": self.theta_deg,
            "v": self.v,
            "n": self.n,
            "zeta": self.zeta,
            "residual": self.residual,
            "min_link_distance_mm": self.min_link_distance_mm,
            "closest_pair": self.closest_pair,
            "feasible": self.feasible,
            "reason": self.reason,
            "path_min_zeta": self.path_min_zeta,
        }
        if self.path is not None:
            rec["path"] = self.path.as_json()
        if self.modes is not None:
            rec["modes"] = [
                {"v": m.v, "n": m.n, "zeta": m.zeta, "residual": m.residual,
                 "home_connected": m.home_connected, "same_sides": m.same_sides}
                for m in self.modes
            ]
        return rec


def fk_result(profile: Profile, model: SpmModel, links: LinkModel, r: FkResult,
              modes: tuple[AssemblyMode, ...] | None = None) -> FkRecord:
    """The record of a solved FK result (``r.ok``), assessed against the profile."""
    if not r.ok or r.pose is None:
        raise ValueError(f"FK was not solved: {r.reason}")
    ws = profile.workspace
    a = assess(model, links, r.pose, ws.zeta_min, (ws.theta_min_deg, ws.theta_max_deg))
    return FkRecord(theta_deg=r.pose.theta_deg, v=r.pose.v, n=r.pose.n, zeta=r.pose.zeta,
                    residual=r.pose.residual, min_link_distance_mm=a.min_link_distance_mm,
                    closest_pair=a.closest_pair, feasible=a.feasible, reason=a.reason,
                    path_min_zeta=r.path_min_zeta, path=fk_path(r), modes=modes)


def fk_record(profile: Profile, model: SpmModel, links: LinkModel, r: FkResult) -> dict[str, object]:
    """The JSON record of one FK result (the CLI's JSON keys, plus ``path`` when known);
    an unsolved one says why."""
    if not r.ok or r.pose is None:
        return {"ok": False, "reason": r.reason, "path_min_zeta": r.path_min_zeta}
    return fk_result(profile, model, links, r).as_json()
