"""Per-leg link arcs (a wrist as built): the unique FK against figures computed with an
independent FK, the inverse kinematics, and the profile's bounds."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.ik import ik

A1 = (-0.4, 0.25, 0.1)
A2 = (0.2, -0.35, 0.3)


def _built(agile: Profile, a1: tuple[float, float, float] = A1,
           a2: tuple[float, float, float] = A2) -> Profile:
    geometry = agile.geometry.model_copy(update={"alpha1_leg_offset_deg": a1,
                                                 "alpha2_leg_offset_deg": a2})
    return agile.model_copy(update={"geometry": geometry})


@pytest.mark.parametrize(("theta_deg", "moved_deg"), [
    ((120.0, 140.0, 125.0), 0.24),
    ((100.0, 100.0, 100.0), 0.47),
    ((95.0, 110.0, 105.0), 0.60),
    ((66.8, 155.0, 131.48), 2.8),  # the paper's MVN goal, near the boundary
])
def test_link_angles_off_by_tenths_move_the_platform_as_an_independent_fk_says(
        agile: Profile, theta_deg: tuple[float, float, float], moved_deg: float) -> None:
    nominal, built = model_of(agile), model_of(_built(agile))
    r0 = nominal.track(np.radians(theta_deg))
    r1 = built.track(np.radians(theta_deg))
    assert r0.ok and r1.ok and r0.pose is not None and r1.pose is not None
    rel = r0.pose.R.T @ r1.pose.R  # each relative to its own home
    angle = np.degrees(np.arccos(np.clip((np.trace(rel) - 1.0) / 2.0, -1.0, 1.0)))
    assert angle == pytest.approx(moved_deg, abs=0.01 if moved_deg < 1 else 0.05)


def test_ik_inverts_the_fk_of_a_wrist_with_unequal_legs(agile: Profile) -> None:
    model = model_of(_built(agile))
    theta = np.radians([95.0, 110.0, 105.0])
    fk = model.track(theta)
    assert fk.ok and fk.pose is not None
    back = ik(model, fk.pose.v)
    assert np.degrees(np.abs(back.theta - theta)).max() < 1e-8


def test_zero_offsets_are_the_symmetric_wrist_and_keep_its_hash(agile: Profile) -> None:
    same = _built(agile, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert same.digest() == agile.digest()
    assert model_of(same).geom.symmetric
    assert _built(agile).digest() != agile.digest()


@pytest.mark.parametrize("bad", [(5.5, 0.0, 0.0), (0.0, -6.0, 0.0)])
def test_arcs_more_than_five_degrees_off_are_refused(agile: Profile, bad: tuple[float, ...]) -> None:
    data = agile.model_dump(mode="json")
    data["geometry"]["alpha2_leg_offset_deg"] = list(bad)
    with pytest.raises(ValidationError, match="alpha2_leg_offset_deg"):
        Profile.model_validate(data)
