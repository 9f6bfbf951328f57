"""The profile of the wrist as the IMU stage found it: its link arcs and its base's tilt
written into a profile, checked as a file would be. Degrees."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from spm_console.config.load import home_signs
from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.commissioning.gravity import built_model
from spm_console.errors import BadInputError, SolverError


def validated(profile: Profile) -> Profile:
    """The profile checked as a file would be (limits' ticks inside the servo's range...)."""
    try:
        return Profile.model_validate(profile.model_dump(mode="python"))
    except ValueError as exc:
        raise BadInputError(f"commission: the profile as built does not validate: {exc}") from None


def with_arcs(profile: Profile, a1: Sequence[float], a2: Sequence[float]) -> Profile:
    """``profile`` with each leg's arcs as fitted (deg from its nominal), its home sign seed
    that of the home pose continued from the profile's own onto those arcs (same assembly and
    working modes, :func:`~spm_console.core.commissioning.gravity.built_model`)."""
    geometry = profile.geometry.model_copy(update={
        "alpha1_leg_offset_deg": tuple(round(float(x), 3) for x in a1),
        "alpha2_leg_offset_deg": tuple(round(float(x), 3) for x in a2)})
    arcs = np.radians([geometry.alpha1_leg_offset_deg, geometry.alpha2_leg_offset_deg])
    try:
        v = built_model(model_of(profile), arcs[0], arcs[1]).v_home
    except SolverError as exc:
        raise BadInputError(f"commission: the arcs as fitted leave no home pose in the profile's "
                            f"modes ({exc.message}); redo the IMU stage") from None
    seed = tuple(home_signs(v.tolist()))  # a component near 0 may cross it with the arcs
    home = profile.home.model_copy(update={"sign_seed": seed})
    out = validated(profile.model_copy(update={"geometry": geometry, "home": home}))
    if not np.allclose(model_of(out).v_home, v, atol=1e-9):
        raise BadInputError("commission: the arcs as fitted make the profile's home another "
                            "assembly mode; redo the IMU stage")
    return out


def with_tilt(profile: Profile, tilt_deg: tuple[float, float]) -> Profile:
    """``profile`` with its base's tilt as fitted (``[plant] base_tilt_deg``, 0.001°): the
    load model's gravity, and its twin's."""
    tilt = (round(float(tilt_deg[0]), 3), round(float(tilt_deg[1]), 3))
    return validated(profile.model_copy(update={
        "plant": profile.plant.model_copy(update={"base_tilt_deg": tilt})}))
