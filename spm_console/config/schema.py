"""Typed, validated prototype profiles (``profiles/*.toml``).

A profile holds everything that is specific to one built wrist: geometry, home
pose, link model, workspace grid, servo model, bus wiring and safety limits.
Angles are in degrees, lengths in mm, times in seconds. A broken file raises
:class:`~spm_console.errors.ProfileError` naming the file, the key, the value and
the allowed range.

Profiles are validated as physics, not only as types: every number is finite and
strict (a bool or a string is never a number; an int is accepted for a float),
every range below keeps the check that uses it meaningful, and the cross-field
checks of :mod:`spm_console.config.checks` (grid size, p·Ts, watchdog, δ, wiring,
home assembly mode) run on load.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, model_validator

from spm_console.config.fields import Angle, Count, Direction, Flag, Real, Section, Sign, Vec3
from spm_console.config.plant import Plant

#: The default profile, relative to the project root / working directory.
DEFAULT_PROFILE = Path("profiles/agile_wrist.toml")


class Meta(Section):
    """Identification of the prototype."""

    name: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9][A-Za-z0-9 ._+-]*$")
    """Short name shown in the UI and logs, and part of the workspace cache's file name:
    1..64 characters, ASCII letters, digits, space, ``.``, ``_``, ``+`` and ``-``, beginning
    with a letter or digit."""
    description: str = Field(default="", max_length=4000)
    """Free text: what the prototype is and where its numbers come from."""


#: Largest per-leg deviation of a link arc from the nominal one, deg (a wrist built that far
#: off is another design, not a tolerance).
MAX_LEG_OFFSET_DEG = 5.0
LegOffset = Annotated[Real, Field(ge=-MAX_LEG_OFFSET_DEG, le=MAX_LEG_OFFSET_DEG)]
LegOffsets = tuple[LegOffset, LegOffset, LegOffset]


class Geometry(Section):
    """SPM geometry (paper Sec. II): link arcs and pyramid angles, degrees."""

    alpha1_deg: Real = Field(gt=0.0, lt=180.0)
    """Proximal link arc α1 (angle between u_i and w_i), 0 < α1 < 180."""
    alpha2_deg: Real = Field(gt=0.0, lt=180.0)
    """Distal link arc α2 (angle between w_i and v_i), 0 < α2 < 180."""
    beta_deg: Real = Field(gt=0.0, lt=90.0)
    """Top pyramid angle β (angle between v_i and the platform normal), 0 < β < 90."""
    gamma_deg: Real = Field(ge=0.0, lt=90.0)
    """Base pyramid angle γ (angle between −u_i and the z axis), 0 ≤ γ < 90; 0 = coaxial shafts."""
    eta_deg: Vec3 = (0.0, 120.0, 240.0)
    """Azimuth η_i of each leg's base axis, eq. (1); each finite, within ±360."""
    alpha1_leg_offset_deg: LegOffsets = (0.0, 0.0, 0.0)
    """Per-leg deviation of each proximal arc from ``alpha1_deg`` as built (commissioning
    fits it), each within ±5°: leg i's arc is α1 + offset[i]."""
    alpha2_leg_offset_deg: LegOffsets = (0.0, 0.0, 0.0)
    """Per-leg deviation of each distal arc from ``alpha2_deg`` as built, each within ±5°."""


class Home(Section):
    """The known home configuration and assembly mode (paper Sec. III, VI-A)."""

    theta_deg: Vec3
    """Motor angles θ at home, each within ±360 and inside its servo limits; the home pose
    there must exist and be non-singular."""
    sign_seed: tuple[Sign, Sign, Sign, Sign, Sign, Sign, Sign, Sign, Sign]
    """Signs (−1, 0, 1) of [v1x v1y v1z v2x ... v3z] at home, eq. (33); selects the home
    assembly mode. Checked on load against v at home: each nonzero component of v must have
    the seed's sign (a component with |v| ≤ 1e-6 matches any entry)."""


#: Largest link radius, mm (10 m: far beyond any wrist, small enough for exact squares).
MAX_RADIUS_MM = 10_000.0


class Links(Section):
    """Segment model of the links for interference checks (paper Sec. IV-B), mm."""

    oa_mm: Real = Field(gt=0.0, le=MAX_RADIUS_MM)
    """|OA_i|: start of the proximal link along u_i, eq. (18); 0 < oa_mm ≤ 10,000 (10 m)."""
    ob_mm: Real = Field(gt=0.0, le=MAX_RADIUS_MM)
    """|OB_i|: middle of the proximal link, eq. (19); 0 < ob_mm ≤ 10,000 (10 m)."""
    oc_mm: Real = Field(gt=0.0, le=MAX_RADIUS_MM)
    """|OC_i|: end of the proximal link along w_i, eq. (20); 0 < oc_mm ≤ 10,000 (10 m)."""
    od_mm: Real = Field(gt=0.0, le=MAX_RADIUS_MM)
    """|OD_i|: start of the distal link along w_i, eq. (21); 0 < od_mm ≤ 10,000 (10 m)."""
    oe_mm: Real = Field(gt=0.0, le=MAX_RADIUS_MM)
    """|OE_i|: middle of the distal link, eq. (22); 0 < oe_mm ≤ 10,000 (10 m)."""
    of_mm: Real = Field(gt=0.0, le=MAX_RADIUS_MM)
    """|OF_i|: end of the distal link along v_i, eq. (23); 0 < of_mm ≤ 10,000 (10 m)."""
    delta_mm: Real = Field(gt=0.0, le=MAX_RADIUS_MM)
    """δ: radius of the capsule around each segment; links collide below 2δ. Must be smaller
    than every radius (OA…OF) of the segments taking part, else the capsules swallow the
    centre and every configuration collides."""
    segments: tuple[Literal["AB", "BC", "DE", "EF"], ...] = ("BC", "DE", "EF")
    """Segments taking part in the interference check (Agile Wrist: AB never collides)."""

    @model_validator(mode="after")
    def _nonempty(self) -> Links:
        if not self.segments or len(set(self.segments)) != len(self.segments):
            raise ValueError("segments must be a non-empty list without repeats")
        return self


class WorkspaceGrid(Section):
    """Grid of motor configurations (paper eq. 25, Sec. VI-D), degrees."""

    theta_min_deg: Angle
    """Lowest grid value of each θ_i, within ±360."""
    theta_max_deg: Angle
    """Highest grid value of each θ_i, within ±360 and above theta_min_deg."""
    step_deg: Real = Field(gt=0.0, le=30.0)
    """Grid spacing Δ, 0 < Δ ≤ 30; the range must be a whole number of steps and the grid
    (range/Δ + 1)³ at most 2,000,000 nodes (≈ 1.4 GB to build, see
    :data:`~spm_console.config.checks.MAX_GRID_NODES`)."""
    zeta_min: Real = Field(gt=0.0, lt=1.0)
    """Conditioning index threshold ζ_min below which a node is singular, 0 < ζ_min < 1."""
    max_halfspaces: Count = Field(default=64, ge=4, le=512)
    """Upper bound on the number of half-spaces of the convex region P, 4..512."""
    refined_cover: Flag = False
    """Refine the region cover near the workspace boundary (grid cells next to infeasible
    nodes checked exactly at Δ/4): ≥ 99 % of the feasible nodes covered instead of ~96 %,
    at the price of a slower build (about 2.5 times the default build's time on the Agile
    Wrist's 2° grid: 2.5–3 s against 1–1.5 s). Every front end and the runtime load that same
    workspace."""

    @property
    def axis_deg(self) -> list[float]:
        """Grid values of one θ_i, degrees."""
        n = round((self.theta_max_deg - self.theta_min_deg) / self.step_deg)
        return [self.theta_min_deg + k * self.step_deg for k in range(n + 1)]


class Identified(Section):
    """Where an identified ``[servo]`` model came from (``identify`` writes it)."""

    date: str = Field(max_length=64)
    """When it was fitted (ISO 8601, UTC)."""
    source: str = Field(max_length=500)
    """What it was fitted to: the experiment's run folder, a run or a CSV file."""
    samples: Count = Field(ge=0, le=10_000_000)
    """Samples fitted (all joints)."""
    fit_rms_deg: Real = Field(ge=0.0, le=360.0)
    """RMS of model − measurement on the fitted samples, deg."""
    held_out_rms_deg: Real | None = Field(default=None, ge=0.0, le=360.0)
    """RMS of model − measurement on held-out samples, deg (None: none held out)."""
    held_out_max_deg: Real | None = Field(default=None, ge=0.0, le=360.0)
    """Largest |model − measurement| on held-out samples, deg."""


class Servo(Section):
    """Closed-loop servo model, eq. (27)-(28), or an identified one with the same state."""

    p: Real = Field(gt=0.0, le=1000.0)
    """Natural frequency ωn, rad/s: with ``zeta = 1`` the double real closed-loop pole at −p
    of (27). 0 < p ≤ 1000, with 1e-3 ≤ p·Ts ≤ 20: below, settling takes over 10,000 samples
    (homing plans hold ⌈10/(p·Ts)⌉ samples); above, the sampled model (28) settles within
    e^−20 in one sample and has no dynamics left."""
    ts_s: Real = Field(ge=0.001, le=1.0)
    """Sampling (reference update) interval Ts, s, 1 ms ≤ Ts ≤ 1 s (one bus cycle of three
    servos needs about a millisecond)."""
    discretization: Literal["zoh", "tustin"] = "zoh"
    """Discretization of (27): exact sampling (zoh) or Tustin."""
    zeta: Real = Field(default=1.0, ge=0.2, le=5.0)
    """Damping ratio ζ, 0.2..5: 1 is the paper's (27); an identified servo may be under- or
    overdamped. Below 0.2 a servo rings for tens of periods and is not a position servo to
    plan for; above 5 one pole is twenty-five times slower than ωn."""
    delay_s: Real = Field(default=0.0, ge=0.0, le=1.0)
    """Transport delay, s, 0 ≤ delay < Ts: the reference sent at t acts from t + delay."""
    linear_range_deg: Real | None = Field(default=None, gt=0.0, le=180.0)
    """Largest |θ* − θ| at which the servo still follows the model, deg (its drive saturates
    beyond). Plans keep every joint within it; none: unbounded, as in the paper."""
    residual_bound_deg: Real | None = Field(default=None, gt=0.0, le=10.0)
    """Largest |model − measurement| seen on held-out data, deg: plans stay this far inside
    the certified set (a tube) and a run whose model error exceeds it is reported as a model
    that looks wrong; none: not known (the paper's exact model)."""
    load_deg_per_nm: Real | None = Field(default=None, gt=0.0, le=100.0)
    """The drive's offset per N·m of the torque that holds the wrist's weight (computed from
    ``[plant]``'s masses, the base's z axis up), deg/(N·m): the inverse of the position loop's
    stiffness, scaled by the mass model's error. With it the runtime sends θ* plus the load's
    offset, so the loaded servo follows the model of θ*; none: no load model (the paper's)."""
    coulomb_deg: Real | None = Field(default=None, ge=0.0, le=5.0)
    """The drive's offset against the motion that the gear's Coulomb friction costs, deg
    (smoothed through rest over 2 deg/s); none: 0."""
    identified: Identified | None = None
    """Provenance of an identified model; none for a model typed in."""

    @model_validator(mode="after")
    def _delay(self) -> Servo:
        if self.delay_s >= self.ts_s:
            raise ValueError(f"servo.delay_s = {self.delay_s} s must be below servo.ts_s = "
                             f"{self.ts_s} s (a delay of a period or more is not modelled)")
        return self


class Limits(Section):
    """Motion limits."""

    vmax_degps: Real = Field(gt=0.0, le=2000.0)
    """Default joint speed bound θ̇_max, deg/s, eq. (30d), 0 < θ̇_max ≤ 2000."""


class JointWiring(Section):
    """Mapping of one joint angle to its servo's ticks."""

    id: Count = Field(ge=0, le=252)
    """Dynamixel ID of the servo driving this joint, 0..252."""
    tick_offset: Count = Field(ge=0, le=4095)
    """Tick value at θ = 0°, modulo one turn: 0..4095 and below ``bus.ticks_per_turn``."""
    tick_trim: Real = Field(default=0.0, ge=-0.5, le=0.5)
    """A fraction of a tick added to ``tick_offset`` (−0.5..0.5): the zero commissioning finds
    between two ticks (a horn's offset is continuous, the servo counts whole ticks)."""
    direction: Direction = 1
    """+1 when ticks grow with θ, −1 otherwise."""
    min_deg: Angle
    """Lowest θ the servo may be commanded to (software limit), within ±360; its tick
    (tick_offset + direction·θ·ticks_per_turn/360) must lie in 0..ticks_per_turn−1."""
    max_deg: Angle
    """Highest θ the servo may be commanded to (software limit), above min_deg, within ±360;
    its tick must lie in 0..ticks_per_turn−1."""


class Bus(Section):
    """Dynamixel servo bus."""

    protocol: Literal["1.0", "2.0"] = "2.0"
    """Dynamixel protocol version spoken by the servos."""
    port: str = ""
    """Serial device (e.g. /dev/ttyUSB0); empty = use the emulated bus."""
    baud: Count = Field(default=1_000_000, ge=7_800, le=10_500_000)
    """Baud rate, bit/s: 7,800..10,500,000 (Dynamixel rates span 7,843 bit/s on protocol 1.0
    to 10.5 Mbit/s on the X series)."""
    timeout_s: Real = Field(default=0.004, ge=0.0001, le=1.0)
    """Reply timeout for one status packet, s, 0.1 ms ≤ timeout ≤ 1 s (no reply crosses a USB
    serial adapter sooner: a USB 2.0 microframe is 0.125 ms)."""
    model_number: Count = Field(default=321, ge=0, le=65535)
    """Expected model number (MX-106: 321 on protocol 2.0, 320 on 1.0); a 2-byte register."""
    ticks_per_turn: Count = Field(default=4096, ge=256, le=1 << 20)
    """Encoder ticks per revolution, 256..1,048,576 (MX-106: 4096; coarser than 1.4°/tick
    makes quantization swamp the tracking check)."""
    joints: tuple[JointWiring, JointWiring, JointWiring]
    """Wiring of joints 1..3."""

    @model_validator(mode="after")
    def _ids(self) -> Bus:
        ids = [j.id for j in self.joints]
        if len(set(ids)) != 3:
            raise ValueError("the three joints need distinct servo ids")
        return self


class Safety(Section):
    """Thresholds of the executor's safety checks."""

    tracking_error_deg: Real = Field(gt=0.0, le=30.0)
    """Largest |measured − model prediction| before a stop, deg: at least 2 encoder ticks
    (2·360/ticks_per_turn, else quantization alone stops a run) and at most 30° (a larger
    gap is a blocked joint or a wrong model, never normal tracking)."""
    comm_failures: Count = Field(ge=1, le=50)
    """Consecutive failed bus cycles before a stop, 1..50 (50 cycles of 20 ms = 1 s blind)."""
    region_margin_deg: Real = Field(ge=0.0, le=10.0)
    """Allowed excursion outside the region P before a stop, deg, 0..10 (five of the paper's
    2° grid steps; a wider margin would in effect switch the region check off)."""
    stop_action: Literal["hold", "torque_off"] = "hold"
    """What a stop does: hold the measured position, or switch torque off."""
    home_speed_degps: Real = Field(ge=0.5, le=360.0)
    """Speed bound of the homing move, deg/s, 0.5 ≤ speed ≤ 360 (slower would take over 6
    minutes for a 180° move)."""
    watchdog_ms: Count = Field(default=100, ge=0, le=2540)
    """Servo Bus Watchdog, ms (0 = off; unit 20 ms, at most 127 units); protocol 2.0 only.
    When on, the value written (rounded to 20 ms) must last at least 2·Ts, or the servos
    stop between two cycles. Off (0) only with :attr:`watchdog_off_reason`: it is what stops
    the servos when the motion process dies."""
    watchdog_off_reason: str = Field(default="", max_length=200)
    """Why the Bus Watchdog is off (``watchdog_ms = 0`` on protocol 2.0): required then, and
    written to every run's log; empty otherwise. One printable line, at most 200 characters."""
    approach_tolerance_deg: Real = Field(default=0.5, gt=0.0, le=5.0)
    """Farther than this from a plan's start (any joint, deg), execution begins with a
    straight approach move at the homing speed; 0 < tolerance ≤ 5. The same rule for every
    front end."""


class Settle(Section):
    """The goal corrected at rest after a planned motion (MVN, minimum time): the servos' own
    P-only position loop leaves an offset that friction and the links' weight set (a few encoder
    ticks on the MX-106, more under load); the runtime then moves the goal it sends by the
    measured offset, a little each period, until the wrist is within ``tolerance_deg`` of the
    plan's goal. Off while ``duration_s`` is 0."""

    duration_s: Real = Field(default=0.0, ge=0.0, le=5.0)
    """Longest settling after the plan, s, 0..5 (0: off; the run ends with the plan)."""
    max_correction_deg: Real = Field(default=0.5, gt=0.0, le=2.0)
    """Largest shift of the goal sent, per joint, deg, 0 < shift ≤ 2; a shifted goal is sent
    only where the safety monitor lets the measured position be (the certified set relaxed by
    ``[safety] region_margin_deg``)."""
    tolerance_deg: Real = Field(default=0.1, gt=0.0, le=1.0)
    """Settled when every joint is this close to the goal for 5 periods, deg (0.1: an encoder
    tick, 0.088°, and a little)."""


class Estimation(Section):
    """Kalman filter noise levels (per joint, model (28))."""

    measurement_noise_deg: Real = Field(ge=1e-6, le=10.0)
    """Standard deviation of a position measurement, deg (quantization ≈ 0.088/√12),
    1e-6..10: the filter squares it (below, the covariance underflows; above, no
    measurement is believed)."""
    process_noise_deg: Real = Field(ge=1e-6, le=10.0)
    """Standard deviation of the unmodelled position disturbance per step, deg, 1e-6..10
    (the filter squares it and divides by Ts)."""


class Emulator(Section):
    """Defaults of the emulated servo bus."""

    noise_deg: Real = Field(default=0.0, ge=0.0, le=10.0)
    """Standard deviation of position noise added before quantization, deg, 0..10."""
    seed: Count = Field(default=0, ge=0, le=(1 << 63) - 1)
    """Random seed of the emulator's noise and faults, 0..2^63−1 (numpy refuses negatives)."""
    link: Literal["socket", "pty"] = "socket"
    """How ``--sim`` runs and the console reach the emulated bus: a Unix-domain ``socket``
    (the bytes cross in the sender's system call) or a ``pty``, a serial device any serial tool
    can open (its bytes wait for a kernel worker, which a loaded machine delays)."""
    clock: Literal["real", "simulated"] = "real"
    """Time on the emulated bus: ``real``, the wall clock (motions take as long as on the
    wrist); ``simulated``, the servo loop, the bus and the emulated wrist in lockstep on a
    shared simulated clock (as fast as the machine computes them, the same every run)."""
    clock_rate: Real = Field(default=0.0, ge=0.0, le=1000.0)
    """With the simulated clock: simulated seconds per wall-clock second, 0..1000 (0: as fast
    as computed; 1: real time, to watch the emulated wrist move). Live following runs at
    real time when 0 (an operator's input comes in real time)."""


class Profile(Section):
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
    plant: Plant = Plant()
    settle: Settle = Settle()

    @property
    def name(self) -> str:
        return self.profile.name

    def with_plant_model(self, model: str) -> Profile:
        """This profile with ``[plant] model`` set to ``model`` (the emulated wrist a run
        chooses: ``--plant``, the console's twin)."""
        if model == self.plant.model:
            return self
        return self.model_copy(update={"plant": self.plant.model_copy(update={"model": model})})

    def digest(self) -> str:
        """SHA-256 of the canonical JSON of every field (the profile's hash)."""
        blob = json.dumps(_digested(self.model_dump(mode="json")), sort_keys=True,
                          separators=(",", ":"))
        return hashlib.sha256(blob.encode()).hexdigest()

    def section_digest(self, *sections: str) -> str:
        """SHA-256 over the named sections only (for cache keys)."""
        data = _digested({s: getattr(self, s).model_dump(mode="json", exclude=_NOT_DIGESTED.get(s))
                          for s in sections})
        blob = json.dumps(data, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(blob.encode()).hexdigest()


#: Build options that change how a result is computed, not what it means: not part of the
#: section digests (plans and caches made before such an option existed keep their hash; the
#: workspace cache key adds ``refined_cover`` itself, and the runtime verifies every plan
#: against its own certified set whatever cover planned it).
_NOT_DIGESTED: dict[str, set[str]] = {"workspace": {"refined_cover"}}
#: Keys added after profiles were hashed, digested only when not at their default (a profile
#: that does not use them keeps its hash, and its caches and plans stay valid).
_DIGESTED_UNLESS_DEFAULT: dict[str, dict[str, object]] = {
    "geometry": {"alpha1_leg_offset_deg": [0.0, 0.0, 0.0],
                 "alpha2_leg_offset_deg": [0.0, 0.0, 0.0]},
    "plant": {"payload_moment_kgmm": None, "payload_kg": None, "base_tilt_deg": [0.0, 0.0]},
    "emulator": {"clock": "real", "clock_rate": 0.0},
}


def _digested(dump: dict[str, object]) -> dict[str, object]:
    """``dump`` (sections by name) without the keys of :data:`_DIGESTED_UNLESS_DEFAULT` that
    hold their default."""
    out = dict(dump)
    for section, defaults in _DIGESTED_UNLESS_DEFAULT.items():
        body = out.get(section)
        if isinstance(body, dict):
            out[section] = {k: v for k, v in body.items()
                            if not (k in defaults and v == defaults[k])}
    return out
