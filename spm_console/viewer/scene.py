"""What the 3D view draws, as numbers: parts, their sizes and their transforms per pose.

Everything here is plain numpy so it can be tested without a viewer. Lengths
come from the profile in mm and are converted to metres for meshcat
(:data:`MM`). Parts:

- ``base``: the triangle through the points A_i and one motor per leg (fixed);
- ``axes/u{i}``: the base joint axes u_i (fixed);
- ``legs/leg{i}/{AB,BC,DE,EF}``: each link segment as a capsule of radius δ
  between the points of eqs. (18)-(23) (``core.links.LinkModel.points``);
- ``axes/w{i}``: the intermediate joint axes w_i(θ);
- ``platform``: a frame rotated by R holding the plate through the F_i, its
  triad, the top joint axes v_i and the normal n.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.links import SEGMENT_ENDS, LinkModel
from spm_console.core.kinematics.model import SpmModel

F = NDArray[np.float64]

#: Metres per millimetre (meshcat works in metres).
MM = 1e-3
#: Every segment drawn, in leg order (the checked ones and the base segment AB).
DRAWN_SEGMENTS: tuple[str, ...] = ("AB", "BC", "DE", "EF")
#: How far the drawn joint axes reach beyond the link points, as a factor.
AXIS_REACH = 1.25


def align_y(d: F) -> F:
    """A rotation (3, 3) taking the y axis (meshcat's cylinder axis) onto unit vector ``d``."""
    d = np.asarray(d, float) / np.linalg.norm(d)
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    x = np.cross(d, helper)
    x /= np.linalg.norm(x)
    z = np.cross(x, d)
    return np.column_stack([x, d, z])


def transform(R: F, t: F) -> F:
    """Homogeneous 4×4 transform from a rotation and a translation (metres)."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def segment_transform(p: F, q: F) -> F:
    """Pose of a y-axis capsule centred on the segment [p, q] (mm in, metres out)."""
    return transform(align_y(np.asarray(q) - np.asarray(p)), 0.5 * (np.asarray(p) + np.asarray(q)) * MM)


@dataclass(frozen=True)
class WristParts:
    """Constant part sizes of one wrist (metres), computed once per profile."""

    delta: float
    """Capsule radius δ, m."""
    segment_length: dict[str, float]
    """Length of each drawn segment (same for every leg), m."""
    base_points: F
    """A_i, (3, 3), m."""
    plate_points: F
    """F_i at home in the platform frame, (3, 3), m."""
    u: F
    """Base joint axes (3, 3)."""
    v_home: F
    """Top joint axes at home (3, 3) = platform frame directions."""
    proximal_reach: float
    """Length of the drawn u_i and w_i axes, m."""
    distal_reach: float
    """Length of the drawn v_i axes and of the normal, m."""


def wrist_parts(model: SpmModel, links: LinkModel) -> WristParts:
    """Sizes of the drawn parts, from the home pose of ``model`` and the link radii."""
    home = model.pose(model.theta_home, np.eye(3))
    w = model.geom.w(model.theta_home)
    pts = links.points(model.u, w, home.v)
    lengths = {
        s: float(np.linalg.norm(pts[SEGMENT_ENDS[s][1]][0] - pts[SEGMENT_ENDS[s][0]][0]) * MM)
        for s in DRAWN_SEGMENTS
    }
    return WristParts(
        delta=links.delta * MM,
        segment_length=lengths,
        base_points=pts["A"] * MM,
        plate_points=pts["F"] * MM,
        u=np.asarray(model.u, float),
        v_home=np.asarray(model.v_home, float),
        proximal_reach=AXIS_REACH * max(links.oa, links.oc) * MM,
        distal_reach=AXIS_REACH * max(links.od, links.of) * MM,
    )


def pose_transforms(model: SpmModel, links: LinkModel, theta_rad: F, R: F) -> dict[str, F]:
    """4×4 transforms (metres) of every moving part for motor angles θ (rad) and rotation R."""
    th = np.asarray(theta_rad, float)
    w = model.geom.w(th)
    v = np.asarray(R, float) @ model.v_home.T
    v = v.T
    pts = links.points(model.u, w, v)
    out: dict[str, F] = {}
    for i in range(3):
        for s in DRAWN_SEGMENTS:
            a, b = SEGMENT_ENDS[s]
            out[f"legs/leg{i + 1}/{s}"] = segment_transform(pts[a][i], pts[b][i])
        out[f"axes/w{i + 1}"] = transform(align_y(w[i]), np.zeros(3))
    out["platform"] = transform(np.asarray(R, float), np.zeros(3))
    return out


def normal_tip_path(normals: F, reach_m: float) -> F:
    """Points (3, K) of the platform normal's tip along a path, metres (meshcat layout)."""
    n = np.asarray(normals, float)
    return np.asarray((n * reach_m).T, dtype=np.float32)
