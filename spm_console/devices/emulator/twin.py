"""The wrist as built, for the emulator: a profile (what the product is told) and an as-built
file (how the wrist differs, :mod:`spm_console.config.as_built`) make a :class:`TrueWrist`, the
truth the emulated bus serves.

Per leg i (the profile's joint i) the truth is:

* its servo's id ``as_built.ids[i]`` and its Drive Mode at power-on (reverse bit set when
  ``as_built.direction[i] = −1``);
* the encoder's own count (Drive Mode 0, Homing Offset 0: how the profile counts), which the
  emulated servo keeps: count = tick_offset_i + p_i·(θ − h_i)·N/360, with the profile's
  ``tick_offset`` and ``direction`` p_i and the horn offset h_i (``horn_offset_deg``: the true
  θ where the profile puts θ = 0); fractional, since a horn's offset is continuous. The horn is
  mechanical: the Drive Mode does not move it;
* the registers at power-on: Present Position = count, or, with the reverse bit set, the count
  mirrored within one turn (:func:`~spm_console.devices.emulator.servo.reversed_zero`), which
  grows with θ as d_i = p_i·as_built.direction[i];
* the link arcs α1 + offset_i + error_i and α2 + offset_i + error_i (the profile's
  ``alpha*_leg_offset_deg`` plus ``alpha*_error_deg``), home at the profile's θ_home;
* the base's tilt, a payload and the IMU's mount (:class:`~spm_console.description.mjcf.AsBuiltBody`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from spm_console.config.as_built import AsBuilt, AsBuiltError
from spm_console.config.schema import Profile
from spm_console.core.kinematics.geometry import SpmGeometry
from spm_console.core.kinematics.model import SpmModel
from spm_console.core.kinematics.modes import home_model
from spm_console.core.kinematics.rotations import rpy_matrix
from spm_console.description.mjcf import AsBuiltBody, base_rotation
from spm_console.devices.dynamixel.tick_map import JointMap
from spm_console.devices.emulator.servo import DRIVE_MODE_REVERSE, reversed_zero


@dataclass(frozen=True)
class TrueJoint:
    """One leg's servo as built."""

    leg: int
    """1-based leg number (the profile's joint)."""
    id: int
    """The servo's id."""
    reverse: bool
    """Drive Mode's reverse bit set at power-on."""
    direction: int
    """+1 when Present Position grows with θ at power-on, −1 otherwise."""
    tick_offset: float
    """Present Position at true θ = 0 at power-on, ticks (fractional)."""
    horn_offset_deg: float
    """The true θ where the encoder's count (Drive Mode 0) is the profile's ``tick_offset``,
    deg."""
    encoder: JointMap
    """The encoder's own count (Drive Mode 0, Homing Offset 0) ↔ true θ: what the emulated
    servo keeps."""

    @property
    def drive_mode(self) -> int:
        """The Drive Mode register at power-on."""
        return DRIVE_MODE_REVERSE if self.reverse else 0

    def present_ticks(self, theta_deg: float) -> float:
        """Present Position (unrounded) at true θ (deg), at power-on."""
        return self.tick_offset + self.direction * theta_deg * self.encoder.ticks_per_deg


@dataclass(frozen=True)
class TrueWrist:
    """The wrist the emulator serves: the truth behind ``profile``."""

    profile: Profile
    """What the product is told."""
    as_built: AsBuilt
    joints: tuple[TrueJoint, TrueJoint, TrueJoint]
    model: SpmModel
    """The true geometry (each leg's arcs) and home pose (R = I at the profile's θ_home)."""
    body: AsBuiltBody
    """Tilt, payload and IMU mount, SI units."""

    @property
    def home_deg(self) -> list[float]:
        """The true θ_home, deg: the profile's home configuration."""
        return [float(x) for x in self.profile.home.theta_deg]

    def encoder_maps(self) -> list[JointMap]:
        """Each leg's encoder count ↔ true θ, in leg order."""
        return [j.encoder for j in self.joints]


def true_wrist(profile: Profile, as_built: AsBuilt, source: str = "as-built") -> TrueWrist:
    """The truth of ``profile``'s wrist built as ``as_built`` (:class:`AsBuiltError` naming
    ``source`` when the two do not fit together)."""
    tpt = profile.bus.ticks_per_turn
    if profile.bus.protocol != "2.0" and -1 in as_built.direction:
        raise AsBuiltError(f"{source}: key 'as_built.direction' = {list(as_built.direction)}: "
                           "the Drive Mode reverse bit is emulated on Protocol 2.0 only (the "
                           f"profile's bus.protocol is {profile.bus.protocol})")
    ids = as_built.ids or tuple(j.id for j in profile.bus.joints)
    joints = []
    for i, wiring in enumerate(profile.bus.joints):
        reverse = as_built.direction[i] < 0
        horn = float(as_built.horn_offset_deg[i])
        per_deg = tpt / 360.0
        # at true θ = 0 (the profile's zero, its trim included, moved by the horn)
        count0 = wiring.tick_offset + wiring.tick_trim - wiring.direction * horn * per_deg
        register0 = reversed_zero(tpt) - count0 if reverse else count0
        encoder = JointMap(i + 1, ids[i], count0, wiring.direction, wiring.min_deg,
                           wiring.max_deg, tpt)
        joint = TrueJoint(i + 1, ids[i], reverse, wiring.direction * as_built.direction[i],
                          register0, horn, encoder)
        at_home = encoder.to_ticks(profile.home.theta_deg[i])
        if not 0 <= at_home <= tpt - 1:
            raise AsBuiltError(
                f"{source}: key 'as_built.horn_offset_deg[{i}]' = {horn:g}: leg {i + 1}'s "
                f"encoder would count {at_home:.0f} at home, outside its 0..{tpt - 1} (the "
                f"profile's tick_offset {wiring.tick_offset} is too near an end of the turn "
                "for it)")
        joints.append(joint)
    g = profile.geometry
    d1 = [a + e for a, e in zip(g.alpha1_leg_offset_deg, as_built.alpha1_error_deg, strict=True)]
    d2 = [a + e for a, e in zip(g.alpha2_leg_offset_deg, as_built.alpha2_error_deg, strict=True)]
    geom = SpmGeometry.from_degrees(g.alpha1_deg, g.alpha2_deg, g.beta_deg, g.gamma_deg,
                                    g.eta_deg, (d1[0], d1[1], d1[2]), (d2[0], d2[1], d2[2]))
    try:
        with np.errstate(all="ignore"):
            model = home_model(geom, np.radians(np.asarray(profile.home.theta_deg, float)),
                               np.asarray(profile.home.sign_seed, float))
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise AsBuiltError(f"{source}: the link arcs as built (alpha1_error_deg "
                           f"{list(as_built.alpha1_error_deg)}, alpha2_error_deg "
                           f"{list(as_built.alpha2_error_deg)}) leave no home pose: {exc}") from None
    roll, pitch, yaw = (math.radians(a) for a in as_built.imu_mount_rpy_deg)
    com = tuple(x / 1000.0 for x in as_built.payload_com_mm)
    body = AsBuiltBody(base_rotation=base_rotation(as_built.base_tilt_deg),
                       imu_rotation=rpy_matrix(roll, pitch, yaw),
                       payload_kg=float(as_built.payload_kg),
                       payload_com_m=(com[0], com[1], com[2]))
    return TrueWrist(profile, as_built, (joints[0], joints[1], joints[2]), model, body)
