"""The wrist as built (devices/emulator/twin.py): what the emulated servos and wrist are, from a
profile and an as-built file."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spm_console.config.as_built import AsBuilt, AsBuiltError, load_as_built
from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.rotations import rpy_matrix
from spm_console.devices.dynamixel.control_table import MX106_P2
from spm_console.devices.dynamixel.tick_map import joint_maps
from spm_console.devices.emulator.servo import EmulatedServo, reversed_zero
from spm_console.devices.emulator.twin import true_wrist
from tests.support.paths import ROOT

TWIN = ROOT / "tests" / "data" / "as_built" / "twin.toml"


def test_a_neutral_as_built_is_the_profiles_wrist(agile: Profile) -> None:
    tw = true_wrist(agile, AsBuilt())
    for j, m in zip(tw.joints, joint_maps(agile), strict=True):
        assert not j.reverse and j.drive_mode == 0 and j.encoder == m
        assert j.id == m.id and j.tick_offset == m.tick_offset and j.direction == m.direction
    assert np.array_equal(tw.model.v_home, model_of(agile).v_home)
    assert tw.model.geom.symmetric and tw.home_deg == list(agile.home.theta_deg)
    assert np.array_equal(tw.body.base_rotation, np.eye(3)) and tw.body.payload_kg == 0.0


def test_ids_directions_and_horns_as_built(agile: Profile) -> None:
    ab = load_as_built(TWIN)
    tw = true_wrist(agile, ab, str(TWIN))
    assert [j.id for j in tw.joints] == [3, 1, 2] == [m.id for m in tw.encoder_maps()]
    assert [j.reverse for j in tw.joints] == [False, True, False]
    assert [j.direction for j in tw.joints] == [1, -1, 1]  # the profile's +1 × as built
    per_deg = 4096 / 360
    for i, (j, wiring) in enumerate(zip(tw.joints, agile.bus.joints, strict=True)):
        horn = ab.horn_offset_deg[i]
        # the horn: the encoder's count (Drive Mode 0) is the profile's tick_offset at θ = horn
        assert j.encoder.to_ticks(horn) == pytest.approx(wiring.tick_offset, abs=1e-9)
        assert j.encoder.to_deg(wiring.tick_offset) == pytest.approx(horn, abs=1e-9)
        # Present Position at power-on: the count, mirrored when reversed
        for th in (100.0, 135.0):
            count = j.encoder.to_ticks(th)
            reg = reversed_zero(4096) - count if j.reverse else count
            assert j.present_ticks(th) == pytest.approx(reg, abs=1e-9)
        # the product (the profile's map) reads a leg counted as it thinks off by the horn
        if not j.reverse:
            assert joint_maps(agile)[i].to_deg(j.present_ticks(135.0)) == pytest.approx(
                135.0 - horn, abs=1e-9)
        assert j.present_ticks(136.0) - j.present_ticks(135.0) == pytest.approx(
            j.direction * per_deg)


def test_an_emulated_servo_at_the_horn_reads_the_profiles_tick_offset(agile: Profile) -> None:
    """Leg 1 (not reversed): at true θ = its horn offset the servo reads the profile's
    tick_offset; leg 2 (reversed) reads it mirrored, and so once its Drive Mode is cleared."""
    tw = true_wrist(agile, load_as_built(TWIN))
    for j, wiring in zip(tw.joints[:2], agile.bus.joints[:2], strict=True):
        s = EmulatedServo(MX106_P2, j.id, 30.0, j.encoder.to_ticks(j.horn_offset_deg), 0.0,
                          drive_mode=j.drive_mode)
        want = reversed_zero(4096) - wiring.tick_offset if j.reverse else wiring.tick_offset
        assert s.present_ticks() == want and bool(s.get("drive_mode") & 1) == j.reverse


def test_the_link_arcs_and_the_body_as_built(agile: Profile) -> None:
    ab = load_as_built(TWIN)
    tw = true_wrist(agile, ab)
    g = tw.model.geom
    want1 = np.radians(np.add(agile.geometry.alpha1_leg_offset_deg, ab.alpha1_error_deg))
    want2 = np.radians(np.add(agile.geometry.alpha2_leg_offset_deg, ab.alpha2_error_deg))
    assert np.allclose(g.d_alpha1, want1) and np.allclose(g.d_alpha2, want2)
    # home at the profile's θ_home, where R = I by construction: the chain closes there
    w = g.w(tw.model.theta_home)
    assert np.abs(np.einsum("ij,ij->i", w, tw.model.v_home) - g.cos_alpha2).max() < 1e-9
    assert np.allclose(tw.model.theta_home, np.radians(agile.home.theta_deg))
    tilt = rpy_matrix(math.radians(3.0), math.radians(-2.0), 0.0)
    assert np.allclose(tw.body.base_rotation, tilt)
    assert np.allclose(tw.body.gravity_mps2, tilt.T @ [0.0, 0.0, -9.81])
    assert tw.body.payload_kg == 0.3 and tw.body.payload_com_m == pytest.approx((0.01, -0.005, 0.12))


def test_as_built_files_that_do_not_fit_the_profile_are_refused(agile: Profile) -> None:
    p1 = agile.model_copy(update={"bus": agile.bus.model_copy(
        update={"protocol": "1.0", "model_number": 320})})
    with pytest.raises(AsBuiltError, match=r"Protocol 2\.0 only"):
        true_wrist(p1, AsBuilt(direction=(1, -1, 1)), "ab.toml")
    true_wrist(p1, AsBuilt(ids=(4, 5, 6)))  # what 1.0 servos can be
    # tick_offset 512 at θ = 0 and home at 135°: the count at home is 2048; a horn of +30°
    # leaves it 1707, in the turn; the count never leaves the servo's turn at home
    true_wrist(agile, AsBuilt(horn_offset_deg=(30.0, -30.0, 0.0)))
    # tick_offset 2250: 160° (the limit) at tick 4070, home at 3786; a horn of −30° puts
    # home at 4127, beyond the turn
    far = agile.bus.joints[0].model_copy(update={"tick_offset": 2250})
    joints = (far, *agile.bus.joints[1:])
    edge = agile.model_copy(update={"bus": agile.bus.model_copy(update={"joints": joints})})
    with pytest.raises(AsBuiltError, match=r"horn_offset_deg\[0\].*outside its 0..4095"):
        true_wrist(edge, AsBuilt(horn_offset_deg=(-30.0, 0.0, 0.0)), "ab.toml")
