"""The record of one FK result (the keys of ``spm-console fk --json``, SPEC §5), shared by the
CLI and the operator runtime. Angles in degrees, lengths in mm."""

from __future__ import annotations

from typing import Any

from spm_console.core.assess import assess
from spm_console.core.kinematics import FkResult, SpmModel
from spm_console.core.links import LinkModel
from spm_console.profile import Profile


def fk_record(profile: Profile, model: SpmModel, links: LinkModel, r: FkResult) -> dict[str, Any]:
    """The JSON record of one FK result (SPEC §5 keys)."""
    if not r.ok or r.pose is None:
        return {"ok": False, "reason": r.reason, "path_min_zeta": r.path_min_zeta}
    ws = profile.workspace
    a = assess(model, links, r.pose, ws.zeta_min, (ws.theta_min_deg, ws.theta_max_deg))
    return {
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
