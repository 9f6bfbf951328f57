"""The wrist as a MuJoCo model (MJCF): the closed chain of an SPM as rigid bodies.

Every joint axis of an SPM passes through its centre, so every body is placed at the origin
with the world's orientation, in the home configuration (joint angles 0 there):

* leg i: a proximal link turning about −u_i (eq. 1: θ_i grows by a rotation about −u_i, as
  ∂w_i/∂θ_i = −u_i × w_i), carrying a distal link turning about w_i(θ_home) (eq. 2);
* the platform hangs from leg 1's distal link by a hinge about v_1;
* legs 2 and 3 close the chain with one ``connect`` equality each, anchored on v_2 and v_3:
  the centre is shared already, so one more common point makes the pair a hinge about v_j.
  The constraints are as stiff as the step allows (time constant two steps).

Masses and the capsules that carry them are the profile's ``[plant]``; joint
friction (Coulomb ``frictionloss``, viscous ``damping``) and the motor's reflected inertia
(``armature``) sit on the servos' drive joints, ``leg<n>_motor_joint`` (names:
:mod:`spm_console.description.names`, legs numbered 1..3). With a gear play
(``[plant] backlash_deg``) that joint turns a rotor body ``leg<n>_rotor`` and the output shaft
(the proximal link, joint ``leg<n>_play_joint``) turns against it within ±half the play (a
joint limit, so MuJoCo's constraint solver takes the impacts); without, the drive turns the
proximal link itself.

Gravity is turned into the base's frame when the base stands tilted (the MJCF's frame is the
base's): the as-built wrist's tilt, else the profile's ``[plant] base_tilt_deg``. A wrist as
built (:class:`AsBuiltBody`, from an as-built file) adds, and only then: its payload welded
to the platform, the IMU's site on the platform with MuJoCo's own ``accelerometer``, ``gyro``
and ``framequat`` sensors on it, and a home jig per leg (a ``joint`` equality holding the
output shaft at home, inactive until the emulator engages it). Without one the text is the
same as ever.

With a link model, each leg also carries the paper's collision envelope (Sec. IV-B): a
capsule of radius δ on every checked segment (A_iB_i, B_iC_i on the proximal link, D_iE_i,
E_iF_i on the distal one, eqs. 18–23), massless and without contact forces (the envelope is a
safety margin around thinner parts, not the parts): MuJoCo's own distance between two legs'
capsules tells when they meet (:class:`~spm_console.devices.emulator.physical.PhysicalWrist`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from xml.sax.saxutils import escape

import numpy as np
from numpy.typing import NDArray

from spm_console.config.plant import PLANT_STEP_S
from spm_console.config.schema import Plant
from spm_console.core.kinematics.links import SEGMENT_ENDS, LinkModel
from spm_console.core.kinematics.loads import GRAVITY_MPS2
from spm_console.core.kinematics.model import SpmModel
from spm_console.core.kinematics.rotations import matrix_quaternion, rpy_matrix
from spm_console.description import names

F = NDArray[np.float64]

#: Radius of the solid sphere whose inertia a payload gets, m (its mass is what matters).
PAYLOAD_RADIUS_M = 0.02


def payload_inertia_kgm2(kg: float) -> float:
    """A payload's inertia about its centre on each axis, kg·m²: a solid sphere's of
    :data:`PAYLOAD_RADIUS_M` (the MJCF and the URDF give it the same)."""
    return 0.4 * kg * PAYLOAD_RADIUS_M**2


@dataclass(frozen=True)
class AsBuiltBody:
    """How the wrist stands and what it carries as built, SI units (from an as-built file)."""

    base_rotation: F
    """World ← base (3, 3): the base turned from level. The MJCF's frame is the base's, so its
    gravity is g_base = Rᵀ·(0, 0, −9.81)."""
    imu_rotation: F
    """Platform ← sensor (3, 3): the IMU's mount."""
    payload_kg: float = 0.0
    """Mass welded to the platform, kg (0: none)."""
    payload_com_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """The payload's centre of mass in the platform frame (the base's at home), m."""

    @property
    def gravity_mps2(self) -> F:
        """Gravity in the base's frame, m/s²."""
        return gravity_in_base(self.base_rotation)


def gravity_in_base(base_rotation: F) -> F:
    """Gravity in the frame of a base turned by ``base_rotation`` (world ← base), m/s²:
    Rᵀ·(0, 0, −9.81)."""
    return np.asarray(base_rotation.T @ np.array([0.0, 0.0, -GRAVITY_MPS2]), float)


def base_rotation(tilt_deg: tuple[float, float]) -> F:
    """World ← base (3, 3) of a base tilted by (about x, then about the world's y) deg:
    R_y·R_x, as an as-built file's and a profile's ``base_tilt_deg`` mean it."""
    return np.asarray(rpy_matrix(math.radians(tilt_deg[0]), math.radians(tilt_deg[1]), 0.0),
                      float)


def imu_position(model: SpmModel, params: PlantParams) -> F:
    """Where the IMU sits on the platform, m (platform frame): the centroid of the platform's
    triangle, r·(v1 + v2 + v3)/3 at home."""
    return np.asarray(params.link_radius_m * model.v_home.mean(axis=0), float)


def _quat_wxyz(R: F) -> F:
    x, y, z, w = matrix_quaternion(np.asarray(R, float))
    return np.array([w, x, y, z])


@dataclass(frozen=True)
class PlantParams:
    """The physical wrist's parameters in SI units (from the profile's ``[plant]``,
    :func:`plant_params`)."""

    supply_v: float
    kt_nm_per_a: float
    resistance_ohm: float
    armature_kgm2: float
    coulomb_nm: float
    viscous_nms: float
    backdrive_friction_nm: float
    link_mass_kg: float
    platform_mass_kg: float
    link_radius_m: float
    backlash_rad: float = 0.0
    """Play of the gear between the rotor and the output shaft, rad (0: rigid)."""
    payload_kg: float = 0.0
    """A payload the profile names (``[plant] payload_kg``), kg (0: none)."""
    payload_com_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Its centre in the platform frame, m."""
    base_tilt_deg: tuple[float, float] = (0.0, 0.0)
    """How the base stands (``[plant] base_tilt_deg``, :func:`base_rotation`), deg."""
    capsule_m: float = 0.008
    """Radius of the capsules that carry the links' mass, m (their inertia only)."""
    timestep_s: float = PLANT_STEP_S
    """Integration step, s (4 kHz; the drives are sampled every step). At 0.5 ms the loop
    closures opened up to 1.2e-5 rad during 5° steps; at 0.25 ms, 2.9e-6 rad. The profile's
    ``plant.armature_kgm2`` is bounded below for this step."""


def plant_params(plant: Plant) -> PlantParams:
    """The ``[plant]`` section in SI units."""
    centre = plant.payload_centre_mm
    return PlantParams(plant.supply_v, plant.kt_nm_per_a, plant.resistance_ohm,
                       plant.armature_kgm2, plant.coulomb_nm, plant.viscous_nms,
                       plant.backdrive_friction_nm, plant.link_mass_kg, plant.platform_mass_kg,
                       plant.link_radius_mm / 1000.0, math.radians(plant.backlash_deg),
                       payload_kg=0.0 if centre is None else float(plant.payload_kg or 0.0),
                       payload_com_m=(0.0, 0.0, 0.0) if centre is None else
                       (centre[0] / 1000.0, centre[1] / 1000.0, centre[2] / 1000.0),
                       base_tilt_deg=(float(plant.base_tilt_deg[0]), float(plant.base_tilt_deg[1])))


def xml_comment(text: str) -> str:
    """``text`` as an XML comment: escaped, and without the "--" a comment may not hold."""
    body = re.sub(r"-(?=-)", "- ", escape(text))
    return f"<!-- {body}{' ' if body.endswith('-') else ''}-->"


def _vec(a: F) -> str:
    return " ".join(f"{float(x):.12g}" for x in a)


@dataclass(frozen=True)
class Capsule:
    """A solid capsule that carries mass: from ``a`` to ``b`` (m, home configuration)."""

    name: str
    a: F
    b: F
    radius_m: float
    mass_kg: float


def body_capsules(model: SpmModel, params: PlantParams) -> dict[str, list[Capsule]]:
    """The capsules that carry each body's mass, by body name (:data:`names.LINKS` less the
    base: "leg1_proximal", "leg1_distal", …, "platform"), in the home configuration: the links are arcs of radius
    ``params.link_radius_m`` about the centre, drawn as chords (u_i→w_i, w_i→v_i, the
    platform's triangle v_a→v_a+1)."""
    u, w, v = model.u, model.geom.w(model.theta_home), model.v_home
    r, c, m = params.link_radius_m, params.capsule_m, params.link_mass_kg
    bodies = {}
    for i in range(3):
        prox, dist = names.proximal_link(i), names.distal_link(i)
        bodies[prox] = [Capsule(f"{prox}_capsule", r * u[i], r * w[i], c, m)]
        bodies[dist] = [Capsule(f"{dist}_capsule", r * w[i], r * v[i], c, m)]
    bodies[names.PLATFORM] = [Capsule(f"{names.PLATFORM}_edge{a + 1}", r * v[a],
                                      r * v[(a + 1) % 3], c, params.platform_mass_kg / 3)
                              for a in range(3)]
    return bodies


def _capsule(cap: Capsule) -> str:
    return (f'<geom name="{cap.name}" type="capsule" fromto="{_vec(cap.a)} {_vec(cap.b)}" '
            f'size="{cap.radius_m:.12g}" mass="{cap.mass_kg:.12g}" contype="0" conaffinity="0"/>')


PROXIMAL_SEGMENTS = ("AB", "BC")
"""Segments on the proximal link (the rest are on the distal link)."""


def envelope_name(leg: int, segment: str) -> str:
    """The name of leg index ``leg``'s envelope capsule on ``segment`` (leg 0:
    "leg1_envelope_BC")."""
    return names.envelope_geom(leg, segment)


def envelope_segments(model: SpmModel, links: LinkModel, leg: int,
                      proximal: bool) -> list[tuple[str, F, F]]:
    """The leg's checked segments on its proximal (or distal) link, at home: (name, a, b), m."""
    pts = links.points(model.u, model.geom.w(model.theta_home), model.v_home)  # mm
    return [(seg, *(pts[e][leg] / 1000.0 for e in SEGMENT_ENDS[seg]))
            for seg in links.segments if (seg in PROXIMAL_SEGMENTS) == proximal]


def _envelopes(model: SpmModel, links: LinkModel | None, leg: int, proximal: bool) -> str:
    if links is None:
        return ""
    return "".join(f'<geom name="{envelope_name(leg, seg)}" type="capsule" '
                   f'fromto="{_vec(a)} {_vec(b)}" size="{links.delta / 1000.0:.6g}" mass="0" '
                   f'contype="0" conaffinity="0" group="3"/>'
                   for seg, a, b in envelope_segments(model, links, leg, proximal))


def _platform_extras(model: SpmModel, params: PlantParams, body: AsBuiltBody | None) -> str:
    """The IMU's site and a payload (the wrist as built's, else the profile's), inside the
    platform's body."""
    if body is None:
        return _payload(params.payload_kg, params.payload_com_m)
    out = (f'<site name="{names.IMU_SITE}" pos="{_vec(imu_position(model, params))}" '
           f'quat="{_vec(_quat_wxyz(body.imu_rotation))}" size="0.005"/>')
    return out + _payload(body.payload_kg, body.payload_com_m)


def _payload(kg: float, com_m: tuple[float, float, float]) -> str:
    """A payload body of ``kg`` centred at ``com_m`` (platform frame, m); "" for none."""
    if kg <= 0.0:
        return ""
    inertia = payload_inertia_kgm2(kg)
    return (f'<body name="{names.PAYLOAD}" pos="{_vec(np.asarray(com_m))}">'
            f'<inertial pos="0 0 0" mass="{kg:.12g}" '
            f'diaginertia="{inertia:.6g} {inertia:.6g} {inertia:.6g}"/></body>')


def _jigs(params: PlantParams, body: AsBuiltBody | None) -> str:
    """One inactive ``joint`` equality per leg holding its output shaft at home (with a gear
    play: the play joint against the rotor, q_play = −q_motor; else the drive joint at 0)."""
    if body is None:
        return ""
    play = params.backlash_rad > 0.0
    out = []
    for i in range(3):
        pair = (f'joint1="{names.play_joint(i)}" joint2="{names.motor_joint(i)}" '
                f'polycoef="0 -1 0 0 0"' if play else
                f'joint1="{names.motor_joint(i)}" polycoef="0 0 0 0 0"')
        out.append(f'<joint name="{names.jig_equality(i)}" {pair} active="false" '
                   f'solref="{2 * params.timestep_s:.6g} 1"/>')
    return "\n    " + "\n    ".join(out)


def _sensors(body: AsBuiltBody | None) -> str:
    if body is None:
        return ""
    site = names.IMU_SITE
    return f"""
  <sensor>
    <accelerometer name="{names.IMU_ACCELEROMETER}" site="{site}"/>
    <gyro name="{names.IMU_GYRO}" site="{site}"/>
    <framequat name="{names.IMU_FRAMEQUAT}" objtype="site" objname="{site}"/>
  </sensor>"""


def wrist_mjcf(model: SpmModel, params: PlantParams, links: LinkModel | None = None,
               body: AsBuiltBody | None = None) -> str:
    """The MJCF text of the wrist in its home configuration (with ``links``, the legs'
    collision envelopes; with ``body``, the wrist as built: tilt, payload, IMU, jigs)."""
    u = model.u
    w = model.geom.w(model.theta_home)
    v = model.v_home
    r = params.link_radius_m
    caps = body_capsules(model, params)
    legs = []
    for i in range(3):
        prox, dist = names.proximal_link(i), names.distal_link(i)
        platform = ""
        if i == 0:
            plat_geoms = "\n".join(_capsule(c) for c in caps[names.PLATFORM])
            plat_geoms += _platform_extras(model, params, body)
            platform = (f'<body name="{names.PLATFORM}"><joint name="{names.platform_joint(0)}" '
                        f'type="hinge" axis="{_vec(v[0])}"/>{plat_geoms}</body>')
        drive = (f'name="{names.motor_joint(i)}" type="hinge" axis="{_vec(-u[i])}" '
                 f'armature="{params.armature_kgm2:.6g}" damping="{params.viscous_nms:.6g}" '
                 f'frictionloss="{params.backdrive_friction_nm:.6g}" '
                 f'solreffriction="{2 * params.timestep_s:.6g} 1"')
        half = math.degrees(params.backlash_rad) / 2.0
        if half > 0.0:  # the rotor turns the output through the gear's play
            head = (f'<body name="{names.rotor_body(i)}"><joint {drive}/>'
                    f'<inertial pos="0 0 0" mass="1e-6" diaginertia="1e-9 1e-9 1e-9"/>'
                    f'<body name="{prox}"><joint name="{names.play_joint(i)}" type="hinge" '
                    f'axis="{_vec(-u[i])}" limited="true" range="{-half:.9g} {half:.9g}" '
                    f'solreflimit="{2 * params.timestep_s:.6g} 1"/>')
            tail = '</body></body>'
        else:
            head = f'<body name="{prox}"><joint {drive}/>'
            tail = '</body>'
        legs.append(
            f'{head}'
            f'{_capsule(caps[prox][0])}'
            f'{_envelopes(model, links, i, True)}'
            f'<body name="{dist}"><joint name="{names.distal_joint(i)}" type="hinge" '
            f'axis="{_vec(w[i])}"/>'
            f'{_capsule(caps[dist][0])}'
            f'{_envelopes(model, links, i, False)}{platform}</body>'
            f'{tail}')
    closures = "\n".join(  # legs 2 and 3 meet the platform on v_2, v_3
        f'<connect body1="{names.distal_link(j)}" body2="{names.PLATFORM}" '
        f'anchor="{_vec(r * v[j])}" solref="{2 * params.timestep_s:.6g} 1" '
        f'solimp="0.99 0.999 0.001"/>' for j in (1, 2))
    motors = "\n".join(f'<motor name="{names.servo_actuator(i)}" joint="{names.motor_joint(i)}" '
                        f'gear="1" ctrllimited="false"/>' for i in range(3))
    # gravity in the base's frame: the as-built wrist's tilt, else the profile's
    gravity = (_vec(body.gravity_mps2) if body is not None else
               f"0 0 {-GRAVITY_MPS2:g}" if params.base_tilt_deg == (0.0, 0.0) else
               _vec(gravity_in_base(base_rotation(params.base_tilt_deg))))
    return f"""<mujoco model="spm_wrist">
  <option timestep="{params.timestep_s:.6g}" gravity="{gravity}" integrator="implicitfast"/>
  <worldbody>
    {"".join(legs)}
  </worldbody>
  <equality>
    {closures}{_jigs(params, body)}
  </equality>
  <actuator>
    {motors}
  </actuator>{_sensors(body)}
</mujoco>"""
