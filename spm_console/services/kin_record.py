"""The record of one FK result (the keys of ``spm-console fk --json``), shared by the
CLI and the operator runtime, and FK with its path (straight from home, else through the
workspace grid). Angles in degrees, lengths in mm."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from spm_console.config.schema import Profile
from spm_console.core.kinematics.assess import assess
from spm_console.core.kinematics.links import LinkModel
from spm_console.core.kinematics.model import FkResult, SpmModel
from spm_console.core.workspace.data import Workspace
from spm_console.core.workspace.fk_path import FkGraph, fk_connected, fk_graph

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


def fk_route(profile: Profile, model: SpmModel, theta_deg: Any, graph: Callable[[], FkGraph],
             start: FkResult | None = None) -> FkResult:
    """Unique FK of θ (deg) with its path: straight from home (or ``start``), else through
    the workspace grid (``graph()`` called only then, and only for θ inside the grid)."""
    w = profile.workspace
    return fk_connected(model, np.radians(np.asarray(theta_deg, float)), graph,
                        (float(w.theta_min_deg), float(w.theta_max_deg)), start)


def path_record(r: FkResult) -> dict[str, Any]:
    """The ``path`` key: route ("straight" or "graph"), waypoints (count), waypoints_deg."""
    return {"route": r.route, "waypoints": len(r.waypoints_deg),
            "waypoints_deg": [list(p) for p in r.waypoints_deg]}


def path_line(rec: dict[str, Any]) -> str:
    """One human line for the ``path`` key of an FK record ("" when absent)."""
    p = rec.get("path")
    if not p:
        return ""
    pts = ["[" + ", ".join(f"{x:.2f}" for x in w) + "]" for w in p["waypoints_deg"]]
    if p["route"] == "straight" and p["waypoints"] == 2:
        return f"path     = straight line from home {pts[0]}°"
    if len(pts) > SHOWN_WAYPOINTS:
        pts = [*pts[:3], "…", *pts[-2:]]
    how = "through the workspace grid (around a singularity)" if p["route"] == "graph" else "via a known pose"
    return f"path     = {p['waypoints']} waypoints {how}: " + " → ".join(pts) + "°"


def fk_record(profile: Profile, model: SpmModel, links: LinkModel, r: FkResult) -> dict[str, Any]:
    """The JSON record of one FK result (the CLI's JSON keys, plus ``path`` when known)."""
    if not r.ok or r.pose is None:
        return {"ok": False, "reason": r.reason, "path_min_zeta": r.path_min_zeta}
    ws = profile.workspace
    a = assess(model, links, r.pose, ws.zeta_min, (ws.theta_min_deg, ws.theta_max_deg))
    rec: dict[str, Any] = {
        "ok": True,
        "theta_deg": r.pose.theta_deg,
        "v": r.pose.v,
        "n": r.pose.n,
        "zeta": r.pose.zeta,
        "residual": r.pose.residual,
        "min_link_distance_mm": a.min_link_distance_mm,
        "closest_pair": a.closest_pair,
        "feasible": a.feasible,
        "reason": a.reason,
        "path_min_zeta": r.path_min_zeta,
    }
    if r.waypoints_deg:
        rec["path"] = path_record(r)
    return rec
