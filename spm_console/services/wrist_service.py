"""The wrist's geometry for one profile, without a bus: unique FK with its path, IK, poses
as the operator gives them, and the workspace (loaded from the cache or built) with its θ
checks. A part of the operator session (:class:`~spm_console.services.session.Session`
holds one as ``session.wrist``). Angles in degrees, lengths in mm.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import link_model_of, model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.ik import ik_rpy
from spm_console.core.kinematics.modes import assembly_modes
from spm_console.core.workspace.build import check_theta
from spm_console.core.workspace.check import ThetaCheck
from spm_console.core.workspace.data import Workspace
from spm_console.errors import BadInputError, Issue, UnreachableError
from spm_console.formatting import fmt_deg
from spm_console.services.kin_record import FkGraphSource, FkRecord, fk_result, fk_route
from spm_console.store.workspace_cache import CacheInfo, load_or_build

F = NDArray[np.float64]

ProgressCallback = Callable[[str, float], None]


def theta3(values: Sequence[float] | F, what: str) -> F:
    """Three finite angles (deg) or BadInputError naming ``what``."""
    try:
        a = np.asarray(values, float).reshape(-1)
    except (TypeError, ValueError):
        raise BadInputError(f"{what}: expected three angles in degrees, got {values!r}") from None
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise BadInputError(f"{what}: expected three finite angles in degrees, got {values!r}")
    return a


@dataclass(frozen=True)
class PoseSpec:
    """How the operator gave a configuration: motor angles, an orientation, or 'current'."""

    kind: Literal["theta", "rpy", "current", "home"]
    values: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """θ1..θ3 (deg) for 'theta'; roll, pitch, yaw from home (deg) for 'rpy'."""

    def describe(self) -> str:
        v = fmt_deg(self.values)  # the format of every other message
        return {"theta": f"θ = {v}", "rpy": f"roll/pitch/yaw = {v}",
                "current": "current pose", "home": "home"}[self.kind]



class WristService:
    """FK, IK and the workspace of one profile's wrist (no bus, no plan)."""

    def __init__(self, profile: Profile, cache_dir: Path | None = None) -> None:
        self.profile = profile
        self.model = model_of(profile)
        self.links = link_model_of(profile)
        self.cache_dir = cache_dir
        self.workspace: Workspace | None = None
        """The loaded workspace (None until loaded or built)."""
        self.cache_info: CacheInfo | None = None
        """How the loaded workspace was obtained (cache hit or build)."""
        self._fk_graph = FkGraphSource(profile, self.model, cache_dir, lambda: self.workspace)

    # ------------------------------------------------------------------ kinematics
    def fk(self, theta_deg: Sequence[float] | F, all_modes: bool = False) -> FkRecord:
        """Unique FK of θ (deg) with its path and quality, around singularities if need be;
        ``all_modes``: with every assembly mode at θ."""
        th = theta3(theta_deg, "θ")
        r = fk_route(self.profile, self.model, th, self._fk_graph)
        if not r.ok or r.pose is None:
            raise UnreachableError(f"θ = {fmt_deg(th)}: {r.reason}")
        modes = tuple(assembly_modes(self.model, r.pose.theta, r.pose.R)) if all_modes else None
        return fk_result(self.profile, self.model, self.links, r, modes)

    def ik(self, rpy_deg: Sequence[float] | F) -> F:
        """θ (deg) for roll, pitch, yaw (deg) from the home orientation."""
        r, p, y = np.radians(theta3(rpy_deg, "roll/pitch/yaw"))
        return np.asarray(ik_rpy(self.model, r, p, y).theta_deg, float)

    def resolve(self, spec: PoseSpec, current_deg: F | None) -> F:
        """Motor angles (deg) of a pose given as θ, as an orientation, as home, or as
        'current' (``current_deg``: the last measured θ, None when unknown)."""
        if spec.kind == "theta":
            return theta3(spec.values, "θ")
        if spec.kind == "rpy":
            return self.ik(spec.values)
        if spec.kind == "home":
            return np.asarray(self.profile.home.theta_deg, float)
        if current_deg is None:
            raise BadInputError("current pose unknown: connect to the servos first",
                                Issue.POSE_UNKNOWN)
        return np.array(current_deg, float)

    # ------------------------------------------------------------------ workspace
    def load_workspace(self, progress: ProgressCallback | None = None,
                       force: bool = False) -> Workspace:
        """Load the cached workspace of the profile, or build (and cache) it."""
        ws, self.cache_info = load_or_build(
            self.profile, cache_dir=self.cache_dir, force=force, progress=progress)
        self.workspace = ws
        return ws

    def ensure_workspace(self) -> Workspace:
        """The loaded workspace, loaded (or built) now when none is: planning and opening a
        plan do not need the workspace step first."""
        return self.workspace if self.workspace is not None else self.load_workspace()

    def require_workspace(self) -> Workspace:
        if self.workspace is None:
            raise BadInputError("no workspace loaded: load or build it first", Issue.NO_WORKSPACE)
        return self.workspace

    def check_theta(self, theta_deg: Sequence[float] | F) -> ThetaCheck:
        """Is θ (deg) feasible and inside P (``core.workspace.check_theta`` -> ThetaCheck)."""
        return check_theta(self.require_workspace(), theta3(theta_deg, "θ"))
