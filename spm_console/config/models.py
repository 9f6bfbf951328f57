"""The one adapter from a profile to the core's frozen models (the core never sees a profile).

A :class:`~spm_console.config.schema.Profile` is validated configuration; the core works on
constant models built from it once: the kinematic model (geometry, home pose and modes),
the link segments, the servo model and the workspace grid specification. Everything above
the core (runtime, cache, front ends) gets its models here. Degrees at this interface.
"""

from __future__ import annotations

import functools

import numpy as np
from numpy.typing import NDArray

from spm_console.config.schema import Profile
from spm_console.core.kinematics.geometry import SpmGeometry
from spm_console.core.kinematics.links import LinkModel
from spm_console.core.kinematics.model import SpmModel
from spm_console.core.kinematics.modes import home_model
from spm_console.core.servo.model import Dynamics, ServoModel, discretize
from spm_console.core.workspace.data import GridSpec, Progress, Workspace
from spm_console.core.workspace.rowmap import serial
from spm_console.core.workspace_build import build_workspace as _build_workspace
from spm_console.system.forked import ForkedRows

F = NDArray[np.float64]


def geometry_of(profile: Profile) -> SpmGeometry:
    g = profile.geometry
    return SpmGeometry.from_degrees(g.alpha1_deg, g.alpha2_deg, g.beta_deg, g.gamma_deg, g.eta_deg,
                                    g.alpha1_leg_offset_deg, g.alpha2_leg_offset_deg)


@functools.lru_cache(maxsize=16)
def _model(geom: SpmGeometry, home: tuple[float, ...], seed: tuple[int, ...]) -> SpmModel:
    return home_model(geom, np.radians(np.asarray(home)), np.asarray(seed, float))


def model_of(profile: Profile) -> SpmModel:
    """The :class:`SpmModel` (geometry + home pose and modes) of a profile (cached)."""
    return _model(geometry_of(profile), tuple(profile.home.theta_deg), tuple(profile.home.sign_seed))


def link_model_of(profile: Profile) -> LinkModel:
    """The link segment model (mm) of a profile."""
    lk = profile.links
    return LinkModel(lk.oa_mm, lk.ob_mm, lk.oc_mm, lk.od_mm, lk.oe_mm, lk.of_mm,
                     lk.delta_mm, tuple(lk.segments))


def servo_model_of(profile: Profile) -> ServoModel:
    """The discretized servo model (28) of a profile (its p or ωn, ζ, delay, Ts and
    discretization)."""
    s = profile.servo
    return discretize(Dynamics(s.p, s.zeta, s.delay_s), s.ts_s, s.discretization)


def servo_limits_deg(profile: Profile) -> tuple[F, F]:
    """(lowest, highest) joint angle of each servo's software limits, deg."""
    return (np.array([j.min_deg for j in profile.bus.joints], float),
            np.array([j.max_deg for j in profile.bus.joints], float))


def servo_tick_deg(profile: Profile) -> float:
    """One encoder tick of the servos, deg (MX-106: 360/4096 ≈ 0.088°)."""
    return 360.0 / float(profile.bus.ticks_per_turn)


def grid_axes_deg(profile: Profile) -> tuple[F, F, F]:
    """The workspace grid values of θ1, θ2, θ3, deg."""
    a = np.asarray(profile.workspace.axis_deg, float)
    return (a, a.copy(), a.copy())


def grid_spec(profile: Profile) -> GridSpec:
    """Everything the core's workspace build needs, from the profile."""
    w = profile.workspace
    return GridSpec(
        model=model_of(profile), links=link_model_of(profile), axes_deg=grid_axes_deg(profile),
        step_deg=w.step_deg, zeta_min=w.zeta_min, max_halfspaces=w.max_halfspaces,
        home_deg=np.asarray(profile.home.theta_deg, float),
        box_deg=(w.theta_min_deg, w.theta_max_deg),
    )


def build_workspace(profile: Profile, progress: Progress | None = None,
                    refined_cover: bool | None = None) -> Workspace:
    """The profile's workspace (grid + region P + region cover, refined near the boundary with
    ``refined_cover``, by default the profile's ``workspace.refined_cover``), built by the core
    from :func:`grid_spec`. The row-wise parts (link distances, the refinement's exact checks,
    the overlap graph's LPs) are split with a forked helper process where that is safe
    (:mod:`spm_console.system.forked`: not from a process running threads or under a real-time
    policy)."""

    if refined_cover is None:
        refined_cover = profile.workspace.refined_cover
    with ForkedRows() as forked:
        # without a helper the serial map keeps the link distances' own progress reports
        return _build_workspace(grid_spec(profile), progress, refined_cover=refined_cover,
                                rowmap=forked if forked.enabled else serial)
