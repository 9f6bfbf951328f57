"""The wrist as a URDF: base, three proximal and three distal links, the platform.

A URDF is a tree, the wrist a closed chain: the tree keeps leg 1 whole (motor, distal and
platform joints) and legs 2 and 3 up to their distal links; the two joints where those meet
the platform are left out. Names (:mod:`spm_console.description.names`, legs numbered
1..3): links ``base_link``, ``leg<n>_proximal``, ``leg<n>_distal``, ``platform``; joints
``leg<n>_motor_joint``, ``leg<n>_distal_joint``, ``leg1_platform_joint``. Every joint's state
at a pose comes from the unique FK (:mod:`spm_console.core.kinematics.joint_states`), which is
what the run logs publish, so robot_state_publisher, RViz or Foxglove draw the whole wrist,
closed, from a log.

Frames as in the MJCF (:mod:`spm_console.description.mjcf`): every joint at the centre, every
link's frame the base's in the home configuration, where every joint is 0; motor joint i turns
about −u_i by θ_i − θ_home,i. Masses and inertias are those of the MJCF's capsules (the same
bodies, :mod:`spm_console.description.inertia`). SI units: m, kg, rad.
"""

from __future__ import annotations

from xml.sax.saxutils import quoteattr

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.links import LinkModel
from spm_console.core.kinematics.model import SpmModel
from spm_console.core.kinematics.rotations import matrix_rpy
from spm_console.description import names
from spm_console.description.inertia import MassProperties, capsule, combined
from spm_console.description.mjcf import (
    PlantParams,
    body_capsules,
    envelope_segments,
    payload_inertia_kgm2,
    xml_comment,
)

F = NDArray[np.float64]


def _vec(a: F) -> str:
    return " ".join(f"{float(x):.12g}" for x in a)


def _z_to(d: F) -> F:
    """A rotation taking the z axis to the unit vector ``d``."""
    z = np.array([0.0, 0.0, 1.0])
    c = float(z @ d)
    axis = np.cross(z, d)
    s = float(np.linalg.norm(axis))
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = axis / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def _cylinder(a: F, b: F, radius: float) -> str:
    """A cylinder from a to b (URDF's cylinder lies along its frame's z)."""
    d = b - a
    length = float(np.linalg.norm(d))
    rpy = matrix_rpy(_z_to(d / length))
    return (f'<origin xyz="{_vec((a + b) / 2)}" rpy="{_vec(rpy)}"/>'
            f'<geometry><cylinder radius="{radius:.6g}" length="{length:.9g}"/></geometry>')


def _inertial(p: MassProperties) -> str:
    i = p.inertia
    return (f'<inertial><origin xyz="{_vec(p.com)}" rpy="0 0 0"/><mass value="{p.mass:.9g}"/>'
            f'<inertia ixx="{i[0, 0]:.9g}" ixy="{i[0, 1]:.9g}" ixz="{i[0, 2]:.9g}" '
            f'iyy="{i[1, 1]:.9g}" iyz="{i[1, 2]:.9g}" izz="{i[2, 2]:.9g}"/></inertial>')


def _envelope(model: SpmModel, links: LinkModel | None, leg: int, proximal: bool) -> str:
    """The paper's collision envelope (Sec. IV-B) on the leg's checked segments: cylinders of
    radius δ (URDF has no capsule)."""
    if links is None:
        return ""
    return "".join(f"<collision name=\"{names.envelope_geom(leg, seg)}\">"
                   f"{_cylinder(a, b, links.delta / 1000.0)}</collision>"
                   for seg, a, b in envelope_segments(model, links, leg, proximal))


def wrist_urdf(model: SpmModel, params: PlantParams, limits_rad: F,
               links: LinkModel | None = None, name: str = "spm_wrist",
               sources: str = "") -> str:
    """The URDF text. ``limits_rad`` (3, 2): each motor joint's range, rad from home;
    ``sources``: a comment naming where the masses and figures come from."""
    u, w, v = model.u, model.geom.w(model.theta_home), model.v_home
    caps = body_capsules(model, params)
    effort = params.kt_nm_per_a * params.supply_v / params.resistance_ohm  # stall torque
    speed = params.supply_v / params.kt_nm_per_a  # no-load speed (back-EMF = supply)
    out = [f'<?xml version="1.0"?>\n<robot name={quoteattr(name)}>']
    if sources:
        out.append(xml_comment(sources))
    out.append(f'<link name="{names.BASE}"/>')

    def link(body: str, proximal_leg: int | None = None, distal_leg: int | None = None) -> str:
        parts = [capsule(c.a, c.b, c.radius_m, c.mass_kg) for c in caps[body]]
        visuals = "".join(f'<visual name="{c.name}">{_cylinder(c.a, c.b, c.radius_m)}</visual>'
                          for c in caps[body])
        env = ""
        if proximal_leg is not None:
            env = _envelope(model, links, proximal_leg, True)
        if distal_leg is not None:
            env = _envelope(model, links, distal_leg, False)
        return f'<link name="{body}">{_inertial(combined(parts))}{visuals}{env}</link>'

    def joint(jname: str, kind: str, parent: str, child: str, axis: F, extra: str = "") -> str:
        return (f'<joint name="{jname}" type="{kind}"><parent link="{parent}"/>'
                f'<child link="{child}"/><origin xyz="0 0 0" rpy="0 0 0"/>'
                f'<axis xyz="{_vec(axis)}"/>{extra}</joint>')

    for i in range(3):
        lo, hi = limits_rad[i]
        prox, dist = names.proximal_link(i), names.distal_link(i)
        out.append(link(prox, proximal_leg=i))
        out.append(joint(names.motor_joint(i), "revolute", names.BASE, prox, -u[i],
                         f'<limit lower="{lo:.12g}" upper="{hi:.12g}" effort="{effort:.6g}" '
                         f'velocity="{speed:.6g}"/><dynamics damping="{params.viscous_nms:.6g}" '
                         f'friction="{params.coulomb_nm:.6g}"/>'))
        out.append(link(dist, distal_leg=i))
        out.append(joint(names.distal_joint(i), "continuous", prox, dist, w[i]))
    out.append(link(names.PLATFORM))
    out.append(joint(names.platform_joint(0), "continuous", names.distal_link(0), names.PLATFORM,
                     v[0]))
    if params.payload_kg > 0.0:  # the profile's payload, welded to the platform
        sphere = MassProperties(params.payload_kg, np.zeros(3),
                                np.eye(3) * payload_inertia_kgm2(params.payload_kg))
        out.append(f'<link name="{names.PAYLOAD}">{_inertial(sphere)}</link>')
        out.append(f'<joint name="{names.PAYLOAD}_weld" type="fixed"><parent '
                   f'link="{names.PLATFORM}"/><child link="{names.PAYLOAD}"/><origin '
                   f'xyz="{_vec(np.asarray(params.payload_com_m))}" rpy="0 0 0"/></joint>')
    out.append(f"<!-- legs 2 and 3 meet the platform about v2 and v3 (joints "
               f"{names.platform_joint(1)} and {names.platform_joint(2)} of the logs); a tree "
               f"cannot close them, the joint states do -->")
    out.append("</robot>")
    return "\n".join(out) + "\n"
