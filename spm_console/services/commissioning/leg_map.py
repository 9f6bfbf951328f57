"""Which leg each servo drives, and which way it counts: from the platform's rotation an IMU
measures while one servo is nudged.

A small move dθ_i of leg i alone turns the platform by dω = J1⁻¹ J2 e_i dθ_i (eqs. 11, 12:
J1 dω = J2 dθ keeps (4) satisfied), an axis fixed in the base frame near home. The IMU on the
platform sees that rotation in its own frame, turned by the platform's pose and its mounting
(together tens of degrees at most); the three legs' axes are far more apart than that, so the
measured axis names the leg (largest |cos|) and its sign the direction the servo counts.
Quaternions (w, x, y, z), degrees at the interface.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.model import SpmModel

F = NDArray[np.float64]

#: Smallest |cos| between the measured rotation axis and the leg's predicted one for a match.
MIN_MATCH_COS = 0.7
#: Smallest platform rotation that counts as "it moved", deg (a nudge of 2° turns it ~1-2°).
MIN_ROTATION_DEG = 0.3


@dataclass(frozen=True)
class LegMatch:
    """One nudged servo's leg and counting direction."""

    id: int
    leg: int
    """1..3."""
    direction: int
    """+1: the servo counts as the joint angle grows (the profile's ``direction``)."""
    rotation_deg: float
    """The platform's measured rotation for the nudge."""
    cos: float
    """|cos| between the measured axis and the leg's predicted one."""
    runner_up_cos: float
    """The best |cos| of another leg (how clear the choice was)."""
    source: str = "imu"
    """"imu" (matched by the measured rotation), or "operator" (confirmed by the operator:
    the rotation and cosines are then 0)."""


#: Below this |vertical component| of the elbow's motion per radian, the operator is asked
#: about its turn seen from above instead of up or down.
MIN_RISE = 0.3


@dataclass(frozen=True)
class ElbowMotion:
    """How leg i's elbow (the end of its proximal link) moves as its joint angle grows, in
    the words an operator watching the wrist uses (the base level, its axis up)."""

    question: str
    """The question asked: "up or down" or "clockwise or counter-clockwise seen from above"."""
    answers: tuple[str, str]
    """The two answers, the first the one a growing joint angle gives."""


def elbow_motions(model: SpmModel, theta_deg: F) -> list[ElbowMotion]:
    """Per leg, how its elbow moves for a growing θ_i at θ (deg): the elbow sits on w_i
    (eq. 2), so it moves along dw_i/dθ_i; up or down when that has a clear vertical part, else
    its turn about the vertical."""
    theta = np.radians(np.asarray(theta_deg, float))
    _p, Q, S = model.geom.ik_coeffs()
    w = model.geom.w(theta)
    dw = -Q * np.sin(theta)[:, None] + S * np.cos(theta)[:, None]
    out = []
    for i in range(3):
        rise = float(dw[i, 2]) / max(float(np.linalg.norm(dw[i])), 1e-12)
        if abs(rise) >= MIN_RISE:
            out.append(ElbowMotion("up or down", ("up", "down") if rise > 0 else ("down", "up")))
        else:
            turn = float(np.cross(w[i], dw[i])[2])
            ccw = ("counter-clockwise", "clockwise")
            out.append(ElbowMotion("clockwise or counter-clockwise seen from above",
                                   ccw if turn > 0 else (ccw[1], ccw[0])))
    return out


def operator_match(ident: int, leg: int, seen: str, motion: ElbowMotion,
                   counted_deg: float) -> LegMatch:
    """The servo ``ident`` drives ``leg`` (1..3), whose elbow the operator saw move ``seen``
    (one of ``motion.answers``) for a nudge of ``counted_deg`` in the servo's counting."""
    grows = seen == motion.answers[0]
    direction = 1 if grows == (counted_deg > 0) else -1
    return LegMatch(ident, leg, direction, 0.0, 0.0, 0.0, source="operator")


def rotation_vector(q_before: F, q_after: F) -> F:
    """The rotation from ``q_before`` to ``q_after`` in the body (sensor) frame, rad: the
    rotation vector of q_before⁻¹ ⊗ q_after."""
    w1, x1, y1, z1 = np.asarray(q_before, float) / np.linalg.norm(q_before)
    w2, x2, y2, z2 = np.asarray(q_after, float) / np.linalg.norm(q_after)
    # conjugate of q1 times q2
    w = w1 * w2 + x1 * x2 + y1 * y2 + z1 * z2
    x = w1 * x2 - x1 * w2 - y1 * z2 + z1 * y2
    y = w1 * y2 + x1 * z2 - y1 * w2 - z1 * x2
    z = w1 * z2 - x1 * y2 + y1 * x2 - z1 * w2
    vec = np.array([x, y, z])
    if w < 0:
        w, vec = -w, -vec
    s = float(np.linalg.norm(vec))
    if s < 1e-15:
        return np.zeros(3)
    return np.asarray(vec / s * 2.0 * math.atan2(s, w), float)


def match_leg(axes: F, ident: int, rotation: F, counted_deg: float) -> LegMatch:
    """The leg whose axis best explains the measured ``rotation`` (rad, sensor frame) of a
    nudge of ``counted_deg`` in the servo's own counting; ValueError when none clearly does."""
    angle = float(np.linalg.norm(rotation))
    if math.degrees(angle) < MIN_ROTATION_DEG:
        raise ValueError(f"servo id {ident}: the platform turned {math.degrees(angle):.2f}° for a "
                         f"{counted_deg:+.1f}° nudge (less than {MIN_ROTATION_DEG:g}°): is the "
                         "IMU on the platform, and the servo driving a leg?")
    unit = rotation / angle
    cos = np.array([float(unit @ a) / float(np.linalg.norm(a)) for a in axes])
    order = np.argsort(-np.abs(cos))
    best = int(order[0])
    if abs(cos[best]) < MIN_MATCH_COS:
        raise ValueError(f"servo id {ident}: the platform turned about an axis no leg explains "
                         f"(best |cos| {abs(cos[best]):.2f} < {MIN_MATCH_COS:g})")
    direction = 1 if cos[best] * counted_deg > 0 else -1
    return LegMatch(ident, best + 1, direction, math.degrees(angle), float(abs(cos[best])),
                    float(abs(cos[order[1]])))
