"""Typed, validated prototype profiles (``profiles/*.toml``).

A profile holds everything that is specific to one built wrist: geometry, home
pose, link model, workspace grid, servo model, bus wiring and safety limits.
Angles are in degrees, lengths in mm, times in seconds. A broken file raises
:class:`~spm_console.errors.ProfileError` naming the file, the key and the reason.
"""

from __future__ import annotations

import hashlib
import json
import math
import tomllib
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from spm_console.errors import ProfileError

#: The default profile, relative to the project root / working directory.
DEFAULT_PROFILE = Path("profiles/agile_wrist.toml")

Vec3 = tuple[float, float, float]


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Meta(_Section):
    """Identification of the prototype."""

    name: str = Field(min_length=1)
    """Short name shown in the UI and logs."""
    description: str = ""
    """Free text: what the prototype is and where its numbers come from."""


class Geometry(_Section):
    """SPM geometry (paper Sec. II): link arcs and pyramid angles, degrees."""

    alpha1_deg: float = Field(gt=0.0, lt=180.0)
    """Proximal link arc α1 (angle between u_i and w_i)."""
    alpha2_deg: float = Field(gt=0.0, lt=180.0)
    """Distal link arc α2 (angle between w_i and v_i)."""
    beta_deg: float = Field(gt=0.0, lt=90.0)
    """Top pyramid angle β (angle between v_i and the platform normal)."""
    gamma_deg: float = Field(ge=0.0, lt=90.0)
    """Base pyramid angle γ (angle between −u_i and the z axis); 0 = coaxial shafts."""
    eta_deg: Vec3 = (0.0, 120.0, 240.0)
    """Azimuth η_i of each leg's base axis, eq. (1)."""


class Home(_Section):
    """The known home configuration and assembly mode (paper Sec. III, VI-A)."""

    theta_deg: Vec3
    """Motor angles θ at home."""
    sign_seed: tuple[int, int, int, int, int, int, int, int, int]
    """Signs of [v1x v1y v1z v2x ... v3z] at home, eq. (33); selects the home assembly mode."""

    @model_validator(mode="after")
    def _signs(self) -> Home:
        if any(s not in (-1, 0, 1) for s in self.sign_seed):
            raise ValueError("sign_seed entries must be -1, 0 or 1")
        return self


class Links(_Section):
    """Segment model of the links for interference checks (paper Sec. IV-B), mm."""

    oa_mm: float = Field(gt=0.0)
    """|OA_i|: start of the proximal link along u_i, eq. (18)."""
    ob_mm: float = Field(gt=0.0)
    """|OB_i|: middle of the proximal link, eq. (19)."""
    oc_mm: float = Field(gt=0.0)
    """|OC_i|: end of the proximal link along w_i, eq. (20)."""
    od_mm: float = Field(gt=0.0)
    """|OD_i|: start of the distal link along w_i, eq. (21)."""
    oe_mm: float = Field(gt=0.0)
    """|OE_i|: middle of the distal link, eq. (22)."""
    of_mm: float = Field(gt=0.0)
    """|OF_i|: end of the distal link along v_i, eq. (23)."""
    delta_mm: float = Field(gt=0.0)
    """δ: radius of the capsule around each segment; links collide below 2δ."""
    segments: tuple[Literal["AB", "BC", "DE", "EF"], ...] = ("BC", "DE", "EF")
    """Segments taking part in the interference check (Agile Wrist: AB never collides)."""

    @model_validator(mode="after")
    def _nonempty(self) -> Links:
        if not self.segments or len(set(self.segments)) != len(self.segments):
            raise ValueError("segments must be a non-empty list without repeats")
        return self


class WorkspaceGrid(_Section):
    """Grid of motor configurations (paper eq. 25, Sec. VI-D), degrees."""

    theta_min_deg: float
    """Lowest grid value of each θ_i."""
    theta_max_deg: float
    """Highest grid value of each θ_i."""
    step_deg: float = Field(gt=0.0, le=30.0)
    """Grid spacing Δ."""
    zeta_min: float = Field(gt=0.0, lt=1.0)
    """Conditioning index threshold ζ_min below which a node is singular."""
    max_halfspaces: int = Field(default=64, ge=4, le=512)
    """Upper bound on the number of half-spaces of the convex region P."""

    @model_validator(mode="after")
    def _range(self) -> WorkspaceGrid:
        if self.theta_max_deg <= self.theta_min_deg:
            raise ValueError("theta_max_deg must be greater than theta_min_deg")
        n = (self.theta_max_deg - self.theta_min_deg) / self.step_deg
        if abs(n - round(n)) > 1e-9:
            raise ValueError("the θ range must be a whole number of steps")
        return self

    @property
    def axis_deg(self) -> list[float]:
        """Grid values of one θ_i, degrees."""
        n = round((self.theta_max_deg - self.theta_min_deg) / self.step_deg)
        return [self.theta_min_deg + k * self.step_deg for k in range(n + 1)]


class Servo(_Section):
    """Closed-loop servo model, eq. (27)-(28)."""

    p: float = Field(gt=0.0, le=1000.0)
    """Double real closed-loop pole at −p, rad/s."""
    ts_s: float = Field(gt=0.0, le=1.0)
    """Sampling (reference update) interval Ts, s."""
    discretization: Literal["zoh", "tustin"] = "zoh"
    """Discretization of (27): exact sampling (zoh) or Tustin."""


class Limits(_Section):
    """Motion limits."""

    vmax_degps: float = Field(gt=0.0, le=2000.0)
    """Default joint speed bound θ̇_max, deg/s, eq. (30d)."""


class JointWiring(_Section):
    """Mapping of one joint angle to its servo's ticks."""

    id: int = Field(ge=0, le=252)
    """Dynamixel ID of the servo driving this joint."""
    tick_offset: int = Field(ge=0, le=4095)
    """Tick value at θ = 0°, modulo 4096 ticks."""
    direction: Literal[1, -1] = 1
    """+1 when ticks grow with θ, −1 otherwise."""
    min_deg: float
    """Lowest θ the servo may be commanded to (software limit)."""
    max_deg: float
    """Highest θ the servo may be commanded to (software limit)."""

    @model_validator(mode="after")
    def _limits(self) -> JointWiring:
        if self.max_deg <= self.min_deg:
            raise ValueError("max_deg must be greater than min_deg")
        return self


class Bus(_Section):
    """Dynamixel servo bus."""

    protocol: Literal["1.0", "2.0"] = "2.0"
    """Dynamixel protocol version spoken by the servos."""
    port: str = ""
    """Serial device (e.g. /dev/ttyUSB0); empty = use the emulated bus."""
    baud: int = Field(default=1_000_000, gt=0)
    """Baud rate, bit/s."""
    timeout_s: float = Field(default=0.004, gt=0.0, le=1.0)
    """Reply timeout for one status packet, s."""
    model_number: int = 321
    """Expected model number (MX-106: 321 on protocol 2.0, 320 on 1.0)."""
    ticks_per_turn: int = Field(default=4096, gt=0)
    """Encoder ticks per revolution."""
    joints: tuple[JointWiring, JointWiring, JointWiring]
    """Wiring of joints 1..3."""

    @model_validator(mode="after")
    def _ids(self) -> Bus:
        ids = [j.id for j in self.joints]
        if len(set(ids)) != 3:
            raise ValueError("the three joints need distinct servo ids")
        return self


class Safety(_Section):
    """Thresholds of the executor's safety checks."""

    tracking_error_deg: float = Field(gt=0.0)
    """Largest |measured − model prediction| before a stop, deg."""
    comm_failures: int = Field(ge=1, le=100)
    """Consecutive failed bus cycles before a stop."""
    region_margin_deg: float = Field(ge=0.0)
    """Allowed excursion outside the region P before a stop, deg."""
    stop_action: Literal["hold", "torque_off"] = "hold"
    """What a stop does: hold the measured position, or switch torque off."""
    home_speed_degps: float = Field(gt=0.0, le=360.0)
    """Speed bound of the homing move, deg/s."""
    watchdog_ms: int = Field(default=100, ge=0, le=2540)
    """Servo Bus Watchdog, ms (0 = off); protocol 2.0 only."""


class Estimation(_Section):
    """Kalman filter noise levels (per joint, model (28))."""

    measurement_noise_deg: float = Field(gt=0.0)
    """Standard deviation of a position measurement, deg (quantization ≈ 0.088/√12)."""
    process_noise_deg: float = Field(gt=0.0)
    """Standard deviation of the unmodelled position disturbance per step, deg."""


class Emulator(_Section):
    """Defaults of the emulated servo bus."""

    noise_deg: float = Field(default=0.0, ge=0.0)
    """Standard deviation of position noise added before quantization, deg."""
    seed: int = 0
    """Random seed of the emulator's noise and faults."""


class Profile(_Section):
    """One prototype. Load with :func:`load_profile`."""

    profile: Meta
    geometry: Geometry
    home: Home
    links: Links
    workspace: WorkspaceGrid
    servo: Servo
    limits: Limits
    bus: Bus
    safety: Safety
    estimation: Estimation
    emulator: Emulator = Emulator()

    @property
    def name(self) -> str:
        return self.profile.name

    def digest(self) -> str:
        """SHA-256 of the canonical JSON of every field (the profile's hash)."""
        blob = json.dumps(self.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(blob.encode()).hexdigest()

    def section_digest(self, *sections: str) -> str:
        """SHA-256 over the named sections only (for cache keys)."""
        data = {s: getattr(self, s).model_dump(mode="json") for s in sections}
        blob = json.dumps(data, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(blob.encode()).hexdigest()


def _key(loc: tuple[int | str, ...]) -> str:
    parts: list[str] = []
    for item in loc:
        if isinstance(item, int):
            parts.append(f"[{item}]")
        else:
            parts.append(("." if parts else "") + item)
    return "".join(parts) or "(top level)"


def parse_profile(data: dict[str, object], source: str) -> Profile:
    """Validate a decoded TOML document; errors name ``source``, the key and the reason."""
    try:
        return Profile.model_validate(data)
    except ValidationError as exc:
        lines = []
        for err in exc.errors():
            reason = err["msg"]
            if err["type"] == "extra_forbidden":
                reason = "unknown key"
            elif err["type"] == "missing":
                reason = "missing key"
            lines.append(f"{source}: key '{_key(tuple(err['loc']))}': {reason}")
        raise ProfileError("\n".join(lines)) from None


def load_profile(path: str | Path = DEFAULT_PROFILE) -> Profile:
    """Read and validate a profile file."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise ProfileError(f"{p}: cannot read profile: {exc.strerror or exc}") from None
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ProfileError(f"{p}: not valid TOML: {exc}") from None
    prof = parse_profile(data, str(p))
    for i, j in enumerate(prof.bus.joints):
        h = prof.home.theta_deg[i]
        if not (j.min_deg <= h <= j.max_deg):
            raise ProfileError(
                f"{p}: key 'bus.joints[{i}]': home θ{i + 1} = {h}° is outside the servo limits "
                f"[{j.min_deg}, {j.max_deg}]°"
            )
    if not all(math.isfinite(x) for x in prof.home.theta_deg):
        raise ProfileError(f"{p}: key 'home.theta_deg': values must be finite")
    return prof
