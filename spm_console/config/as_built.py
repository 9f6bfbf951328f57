"""The wrist as it was built (``--as-built FILE.toml``): what the emulated wrist is, whatever its
profile says, so commissioning can be tested against a truth the product is not told.

A profile is what the product is told about a wrist; an as-built file says how the emulated one
differs from it: which servo sits on which leg, which servo counts the other way (its Drive Mode
reverse bit), how far each horn sits from the profile's zero, each leg's link arcs, the base's
tilt, the IMU's mount and a payload. Every key is optional and neutral by default (an empty file
is the profile's wrist). Degrees, mm, kg; a broken file fails like a profile, naming the file,
the key, the value and the allowed range (:class:`AsBuiltError`, exit 4)::

    [as_built]
    ids = [3, 1, 2]                # the servo id on leg 1, 2, 3
    direction = [1, -1, 1]         # -1: that leg's servo has its Drive Mode reverse bit set
    horn_offset_deg = [4.0, -7.5, 0.0]
    alpha1_error_deg = [0.3, -0.2, 0.0]
    alpha2_error_deg = [0.0, 0.1, -0.4]
    base_tilt_deg = [2.0, -1.0]
    imu_mount_rpy_deg = [0.0, 0.0, 90.0]
    payload_kg = 0.3
    payload_com_mm = [0.0, 0.0, 120.0]
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

from pydantic import Field, ValidationError, model_validator

from spm_console.config.checks import show, validation_message
from spm_console.config.fields import Count, Direction, Real, Section
from spm_console.errors import BadInputError
from spm_console.safe_io import parse_toml, read_text

#: Largest as-built file read (a complete one is under 1 kB).
MAX_AS_BUILT_BYTES = 64 * 1024
#: Largest |horn offset|, deg: a horn mounted a few spline teeth off, not another joint.
MAX_HORN_OFFSET_DEG = 30.0
#: Largest |link arc error|, deg: a machining or assembly tolerance, not another design.
MAX_ARC_ERROR_DEG = 2.0
#: Largest |base tilt| about each axis, deg: a bench that is not level, not a wall mount.
MAX_TILT_DEG = 10.0
#: Largest |IMU mount angle| about each axis, deg.
MAX_IMU_MOUNT_DEG = 30.0
#: Heaviest payload, kg (the MX-106 holds 8.4 N·m stalled: 2 kg at 0.2 m is half of it).
MAX_PAYLOAD_KG = 2.0
#: Farthest payload centre of mass from the wrist's centre along each axis, mm.
MAX_PAYLOAD_COM_MM = 200.0

ServoId = Annotated[Count, Field(ge=0, le=252)]
HornOffset = Annotated[Real, Field(ge=-MAX_HORN_OFFSET_DEG, le=MAX_HORN_OFFSET_DEG)]
ArcError = Annotated[Real, Field(ge=-MAX_ARC_ERROR_DEG, le=MAX_ARC_ERROR_DEG)]
Tilt = Annotated[Real, Field(ge=-MAX_TILT_DEG, le=MAX_TILT_DEG)]
MountAngle = Annotated[Real, Field(ge=-MAX_IMU_MOUNT_DEG, le=MAX_IMU_MOUNT_DEG)]
ComMm = Annotated[Real, Field(ge=-MAX_PAYLOAD_COM_MM, le=MAX_PAYLOAD_COM_MM)]


class AsBuiltError(BadInputError):
    """An as-built file is missing, unreadable or invalid, or does not fit the profile it is
    applied to (names the file, the key, the value and the allowed range)."""


class AsBuilt(Section):
    """How the emulated wrist differs from its profile (``[as_built]``); every key neutral by
    default. Per-leg lists are in leg order (legs 1, 2, 3: the profile's joints 1, 2, 3)."""

    ids: tuple[ServoId, ...] = ()
    """The servo id on leg 1, 2, 3: three distinct ids, each 0..252 (empty, the default: the
    profile's ``bus.joints[*].id``)."""
    direction: tuple[Direction, Direction, Direction] = (1, 1, 1)
    """Per leg, −1 when its servo has the Drive Mode reverse bit (address 10, bit 0) set: its
    Present Position counts the other way than the profile's ``direction`` says, mirrored
    within one turn (+1: as the profile says). Protocol 2.0 only."""
    horn_offset_deg: tuple[HornOffset, HornOffset, HornOffset] = (0.0, 0.0, 0.0)
    """Per leg, the true joint angle θ (deg) when the servo, counting as the profile says
    (Drive Mode 0), reads the profile's ``tick_offset`` (where the profile puts θ = 0): a horn
    mounted off, each within ±30°. Mechanical: a reverse bit mirrors the count, not the horn."""
    alpha1_error_deg: tuple[ArcError, ArcError, ArcError] = (0.0, 0.0, 0.0)
    """Per leg, the true proximal arc minus the profile's (α1 plus its
    ``alpha1_leg_offset_deg``), deg, each within ±2."""
    alpha2_error_deg: tuple[ArcError, ArcError, ArcError] = (0.0, 0.0, 0.0)
    """Per leg, the true distal arc minus the profile's, deg, each within ±2."""
    base_tilt_deg: tuple[Tilt, Tilt] = (0.0, 0.0)
    """The base rotated from level about the world's x axis, then about the world's y axis,
    deg, each within ±10 (R_tilt = R_y·R_x; the world's z axis points up, against gravity)."""
    imu_mount_rpy_deg: tuple[MountAngle, MountAngle, MountAngle] = (0.0, 0.0, 0.0)
    """The IMU's rotation relative to the platform frame as fixed-axis roll, pitch, yaw
    (R = R_z(yaw)·R_y(pitch)·R_x(roll), platform ← sensor), deg, each within ±30."""
    payload_kg: Real = Field(default=0.0, ge=0.0, le=MAX_PAYLOAD_KG)
    """Mass of a payload welded to the platform, kg, 0..2 (0: none)."""
    payload_com_mm: tuple[ComMm, ComMm, ComMm] = (0.0, 0.0, 0.0)
    """The payload's centre of mass in the platform frame (origin at the wrist's centre, where
    every joint axis meets; axes the base's at home), mm, each within ±200."""

    @model_validator(mode="after")
    def _three_distinct_ids(self) -> AsBuilt:
        if self.ids and (len(self.ids) != 3 or len(set(self.ids)) != 3):
            raise ValueError(f"ids = {show(list(self.ids))} ({len(self.ids)} given): three "
                             "distinct ids, one per leg, please "
                             "(or none: the profile's)")
        return self

    @property
    def neutral(self) -> bool:
        """Whether every key holds its default: the wrist is the profile's."""
        return self == AsBuilt()


class AsBuiltFile(Section):
    """An as-built file: one optional ``[as_built]`` table."""

    as_built: AsBuilt = AsBuilt()
    """How the emulated wrist differs from its profile."""


def parse_as_built(data: dict[str, object], source: str) -> AsBuilt:
    """A decoded as-built TOML document, validated; errors name ``source``, the key, the value
    and the allowed range."""
    try:
        return AsBuiltFile.model_validate(data).as_built
    except ValidationError as exc:
        raise AsBuiltError(validation_message(exc, source, AsBuiltFile)) from None


def parse_as_built_text(text: str, source: str) -> AsBuilt:
    """An as-built file's TOML text, validated as :func:`load_as_built` validates a file."""
    data = parse_toml(text, source, AsBuiltError,
                      "not an as-built file: values nested too deeply")
    return parse_as_built(data, source)


def load_as_built(path: str | Path) -> AsBuilt:
    """Read and validate an as-built file (at most :data:`MAX_AS_BUILT_BYTES`, a regular file,
    UTF-8)."""
    text = read_text(path, "as-built file", MAX_AS_BUILT_BYTES, AsBuiltError)
    return parse_as_built_text(text, str(path))
