"""Build the constant kinematic model of a profile (cached per profile geometry)."""

from __future__ import annotations

import functools

import numpy as np

from spm_console.core.geometry import SpmGeometry
from spm_console.core.kinematics import SpmModel
from spm_console.core.links import LinkModel
from spm_console.core.modes import home_model
from spm_console.profile import Profile


def geometry_of(profile: Profile) -> SpmGeometry:
    g = profile.geometry
    return SpmGeometry.from_degrees(g.alpha1_deg, g.alpha2_deg, g.beta_deg, g.gamma_deg, g.eta_deg)


@functools.lru_cache(maxsize=16)
def _model(geom: SpmGeometry, home: tuple[float, ...], seed: tuple[int, ...]) -> SpmModel:
    return home_model(geom, np.radians(np.asarray(home)), np.asarray(seed, float))


def model_of(profile: Profile) -> SpmModel:
    """The :class:`SpmModel` (geometry + home pose and modes) of a profile."""
    return _model(geometry_of(profile), tuple(profile.home.theta_deg), tuple(profile.home.sign_seed))


def link_model_of(profile: Profile) -> LinkModel:
    """The link segment model (mm) of a profile."""
    lk = profile.links
    return LinkModel(lk.oa_mm, lk.ob_mm, lk.oc_mm, lk.od_mm, lk.oe_mm, lk.of_mm,
                     lk.delta_mm, tuple(lk.segments))
