"""The ``[plant]`` section: the emulated wrist behind ``--sim`` (the physical emulator's
figures, SI units at the output shaft), each key bounded below by the size at which the
figure still means something physical and the emulated wrist stays stable.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Annotated, Literal, get_args

from pydantic import Field, model_validator

from spm_console.config.fields import Real, Section

#: The physical emulator's integration step, s, and the damping of the stop that holds a
#: stalled shaft (fault ``stall``), N·m·s/rad: the drive's torque, its back-EMF damping kt²/R
#: and that stop act on the rotor's inertia once a step, explicitly, which stays stable only
#: while step × damping / inertia < 2 (the armature's bound keeps half of that).
PLANT_STEP_S = 0.00025
STALL_DAMPING_NMS = 20.0
#: Largest component of a payload's first moment, kg·mm (5 kg a metre from the centre: far
#: beyond what an MX-106 wrist holds, small enough to stay a load and not another machine).
MAX_PAYLOAD_MOMENT_KGMM = 5000.0
Moment = Annotated[Real, Field(ge=-MAX_PAYLOAD_MOMENT_KGMM, le=MAX_PAYLOAD_MOMENT_KGMM)]
#: Heaviest payload a profile may name, kg (the MX-106 holds 8.4 N·m stalled: 2 kg at 0.2 m
#: is half of it), and the farthest its centre may sit from the wrist's along an axis, mm.
MAX_PAYLOAD_KG = 2.0
MAX_PAYLOAD_CENTRE_MM = 300.0
#: Largest base tilt about each axis, deg: a bench that is not level, not a wall mount.
MAX_BASE_TILT_DEG = 10.0
Tilt = Annotated[Real, Field(ge=-MAX_BASE_TILT_DEG, le=MAX_BASE_TILT_DEG)]
#: The emulated wrists ``[plant] model`` (and ``--plant``) choose from.
PlantModel = Literal["ideal", "physical"]
PLANT_MODELS: tuple[str, ...] = get_args(PlantModel)


class Plant(Section):
    """The emulated wrist behind ``--sim``: ``ideal`` servos that are eq. (27) with ``servo.p``,
    or the ``physical`` wrist (MX-106 drives on the rigid-body closed chain, MuJoCo). Figures
    at the output shaft, after the 225:1 gear; each names its source. Each lower bound is a
    size below which the figure means nothing physical (or the emulated wrist goes unstable)."""

    model: PlantModel = "ideal"
    """Which emulated wrist ``--sim`` runs."""
    supply_v: Real = Field(default=12.0, ge=1.0, le=30.0)
    """Supply voltage, V, 1..30: the MX-106 e-manual's 12 V rating."""
    kt_nm_per_a: Real = Field(default=2.2, ge=0.01, le=20.0)
    """Torque constant, N·m/A, 0.01..20: BAM (arXiv 2410.08650) identified 2.19–2.23 on the
    MX-106."""
    resistance_ohm: Real = Field(default=3.14, ge=0.01, le=100.0)
    """Winding resistance, Ω, 0.01..100: kt·V / 8.4 N·m, the e-manual's stall torque at 12 V
    (BAM: 2–3)."""
    armature_kgm2: Real = Field(default=0.026, ge=0.005, le=10.0)
    """Rotor inertia reflected through the gear, kg·m²: BAM, 0.025–0.027. At least
    PLANT_STEP_S·(kt²/R + STALL_DAMPING_NMS) (0.0054 with the other defaults): below, the
    emulated wrist is unstable (it read 179.7° before any command at 1e-320)."""
    coulomb_nm: Real = Field(default=0.1, ge=0.0, le=10.0)
    """Coulomb friction, N·m: BAM, about 0.10."""
    viscous_nms: Real = Field(default=0.04, ge=0.0, le=10.0)
    """Viscous friction, N·m·s/rad: BAM, 0.035–0.051."""
    backlash_deg: Real = Field(default=0.33, ge=0.0, le=5.0)
    """Play of the gear train at the output, deg: the MX-106 e-manual's 0.33° (20′). The
    encoder reads the output shaft, so the play sits inside the position loop. 0: none."""
    backdrive_friction_nm: Real = Field(default=1.0, ge=0.0, le=20.0)
    """Friction of a joint whose torque is off (the gear driven from the output), N·m:
    assumed, so that the wrist's own weight (below 0.5 N·m at any joint with the default
    masses) does not turn a 225:1 gear train, as it does not on the bench."""
    link_mass_kg: Real = Field(default=0.12, ge=0.001, le=10.0)
    """Mass of each proximal and distal link, kg, 0.001..10: assumed (an aluminium arc of
    about 10 cm). Below a gram the rigid-body model loses its links (a nanogram goes unstable,
    MuJoCo refuses less)."""
    platform_mass_kg: Real = Field(default=0.25, ge=0.001, le=50.0)
    """Mass of the platform with its load, kg, 0.001..50: assumed."""
    link_radius_mm: Real = Field(default=100.0, ge=1.0, le=1000.0)
    """Distance from the centre at which the links' mass is carried, mm, 1..1000: assumed."""
    payload_moment_kgmm: tuple[Moment, Moment, Moment] | None = None
    """First moment m·c of what sits on the platform beyond ``platform_mass_kg``, kg·mm, in
    the platform's frame at home, each component within ±5000 (commissioning fits it from the
    offsets the servos hold the wrist at; statics see m·c, not the mass). The load model adds
    it to the platform's weight (the torque that holds the wrist); the emulated wrist and the
    exported descriptions carry it only with ``payload_kg``. None: no payload."""
    payload_kg: Real | None = Field(default=None, gt=0.0, le=MAX_PAYLOAD_KG)
    """The payload's mass, kg, 0..2, weighed (a wrist cannot tell it: a body turning about a
    fixed point shows its first and second moments only). With ``payload_moment_kgmm`` it puts
    the payload's centre at m·c / m, and the emulated wrist and the exported descriptions
    carry it there. None: not known."""
    base_tilt_deg: tuple[Tilt, Tilt] = (0.0, 0.0)
    """How the base stands in the world, deg, each within ±10: turned about the world's x by
    the first, then about its y by the second (R_tilt = R_y·R_x; commissioning fits it from
    the gravity an IMU on the platform measures). The load model's gravity and the emulated
    wrist's are turned with it. (0, 0): level, the base's z axis up."""

    @model_validator(mode="after")
    def _integrable(self) -> Plant:
        emf = self.kt_nm_per_a**2 / self.resistance_ohm
        least = PLANT_STEP_S * (emf + STALL_DAMPING_NMS)
        if self.armature_kgm2 < least:
            raise ValueError(
                f"plant.armature_kgm2 = {self.armature_kgm2:g} kg·m² is below {least:.3g}: the "
                f"drive's back-EMF damping kt²/R = {emf:.3g} N·m·s/rad (with a stalled shaft's "
                f"{STALL_DAMPING_NMS:g}) makes the emulated wrist unstable at its "
                f"{PLANT_STEP_S * 1e3:g} ms step (allowed: armature_kgm2 ≥ {least:.3g} for "
                "these kt_nm_per_a and resistance_ohm)")
        if self.payload_kg is not None:
            if self.payload_moment_kgmm is None:
                raise ValueError("plant.payload_kg needs plant.payload_moment_kgmm (where the "
                                 "payload sits: commissioning fits it)")
            centre = self.payload_centre_mm
            assert centre is not None
            if not centre_within(self.payload_moment_kgmm, float(self.payload_kg)):
                raise ValueError(
                    f"plant.payload_moment_kgmm / payload_kg puts the payload's centre at "
                    f"({', '.join(f'{c:.0f}' for c in centre)}) mm, beyond "
                    f"±{MAX_PAYLOAD_CENTRE_MM:g} mm of the wrist's centre: check both")
        return self

    @property
    def payload_centre_mm(self) -> tuple[float, float, float] | None:
        """Where the payload sits in the platform's frame, mm: m·c / m (None: no mass)."""
        if self.payload_kg is None or self.payload_moment_kgmm is None:
            return None
        m = float(self.payload_kg)
        c = [float(x) / m for x in self.payload_moment_kgmm]
        return (c[0], c[1], c[2])


def centre_within(moment_kgmm: Sequence[float], mass_kg: float) -> bool:
    """Whether a payload of ``mass_kg`` with first moment ``moment_kgmm`` sits within
    ±MAX_PAYLOAD_CENTRE_MM of the wrist's centre on every axis (the one rule of where a
    profile may place a payload)."""
    return mass_kg > 0.0 and max(abs(float(x)) for x in moment_kgmm) / mass_kg <= MAX_PAYLOAD_CENTRE_MM
