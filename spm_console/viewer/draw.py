"""The meshcat scene of the wrist: what is sent once (:func:`build_scene`) and per pose.

Scene tree (paths under ``/meshcat``):

- ``base``, ``axes/u{i}``: the fixed base (triangle through the A_i, motors, base axes);
- ``labels/leg{i}``: the text "leg i" beside motor i (legs are coloured red, blue,
  yellow in order, in both wrists below); ``labels/unknown``: "measured pose unknown",
  shown while the solid wrist is hidden;
- ``measured/…``: the wrist where the servos say it is, opaque, labelled "measured";
- ``target/…``: the same parts as a translucent ghost (:data:`GHOST_OPACITY`),
  labelled "target": a pose the wrist is *not* known to be in (a plan's goal, an
  FK/IK or workspace result);
- ``path``: the planned path, as the trace of the platform normal's tip (a line and a
  dot per sample).

Under ``measured`` and ``target`` the moving parts are ``legs/leg{i}/{AB,BC,DE,EF}``,
``axes/w{i}`` and ``platform`` (names from :func:`scene.pose_transforms`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from spm_console.viewer import scene

if TYPE_CHECKING:
    from spm_console.viewer.client import MeshcatClient

F = NDArray[np.float64]

#: Leg colours, legs 1..3 (red, blue, yellow), 0xRRGGBB.
LEG_COLORS = (0xD1495B, 0x2E86AB, 0xEDAE49)
#: Colour of the planned path.
PATH_COLOR = 0xFF00FF
#: Size of the dots marking the path's samples, m.
PATH_DOT_M = 0.004
#: Opacity of the target ghost (the measured wrist is opaque).
GHOST_OPACITY = 0.3
#: Colour of the platform plate.
PLATE_COLOR = 0x9AA5B8
#: Background gradient, top and bottom (RGB in 0..1, as the page wants it): light, so
#: that the black label text and the translucent ghost read well.
BACKGROUND = ((0.98, 0.98, 0.98), (0.76, 0.78, 0.82))
#: Camera position (m, in meshcat's y-up camera frame), looking at the origin.
CAMERA_POSITION = (0.24, 0.17, 0.24)
#: Label sizes, m (the sprite's width; the text fills part of it).
LEG_LABEL_M = 0.06
POSE_LABEL_M = 0.07
CAPTION_M = 0.16


@dataclass(frozen=True)
class Look:
    """How one wrist (measured or target) is drawn."""

    root: str
    """Scene path of its group (``measured`` or ``target``)."""
    opacity: float
    label: str
    label_reach: float
    """Where its label sits along the platform normal, as a factor of the distal reach."""


MEASURED = Look("measured", 1.0, "measured", 1.1)
TARGET = Look("target", GHOST_OPACITY, "target", 1.3)


def _material(color: int, opacity: float) -> object:
    import meshcat.geometry as g

    if opacity >= 1.0:
        return g.MeshLambertMaterial(color=color)
    # front faces only and no depth writes: one even veil that hides nothing behind it
    return g.MeshLambertMaterial(color=color, opacity=opacity, side=0, depthWrite=False)


def _axis(c: MeshcatClient, name: str, length: float, color: int, opacity: float = 1.0) -> None:
    """A thin line from the origin along the frame's y axis (oriented by its transform)."""
    import meshcat.geometry as g

    pts = np.array([[0.0, 0.0], [0.0, length], [0.0, 0.0]], dtype=np.float32)
    mat = (g.LineBasicMaterial(color=color) if opacity >= 1.0
           else g.LineBasicMaterial(color=color, opacity=opacity, depthWrite=False))
    c.set_object(name, g.Line(g.PointsGeometry(pts), mat))


def normal_home(parts: scene.WristParts) -> F:
    """Unit platform normal at home, in the platform frame."""
    s = parts.v_home.sum(0)
    return np.asarray(s / np.linalg.norm(s), float)


def build_wrist(c: MeshcatClient, parts: scene.WristParts, look: Look) -> None:
    """Send the moving parts of one wrist (legs, w axes, platform) under ``look.root``."""
    import meshcat.geometry as g

    p, root, op = parts, look.root, look.opacity
    for i in range(3):
        mat = _material(LEG_COLORS[i], op)
        for s in scene.DRAWN_SEGMENTS:
            L = p.segment_length[s]
            name = f"{root}/legs/leg{i + 1}/{s}"
            c.set_object(f"{name}/body", g.Cylinder(L, radius=p.delta), mat)
            if op < 1.0:
                continue  # no joint balls on the ghost: overlapping veils would look solid
            for k, y in (("end0", -L / 2), ("end1", L / 2)):
                c.set_object(f"{name}/{k}", g.Sphere(p.delta), mat)
                c.set_transform(f"{name}/{k}", scene.transform(np.eye(3), np.array([0, y, 0])))
        _axis(c, f"{root}/axes/w{i + 1}", p.proximal_reach, LEG_COLORS[i], op)
        _axis(c, f"{root}/platform/v{i + 1}", p.distal_reach, LEG_COLORS[i], op)
        c.set_transform(f"{root}/platform/v{i + 1}",
                        scene.transform(scene.align_y(p.v_home[i]), np.zeros(3)))
    plate = g.TriangularMeshGeometry(p.plate_points, np.array([[0, 1, 2], [0, 2, 1]]))
    c.set_object(f"{root}/platform/plate", plate, _material(PLATE_COLOR, min(op, 0.85)))
    if op >= 1.0:
        c.set_object(f"{root}/platform/frame", g.triad(0.6 * p.distal_reach))
    n = normal_home(p)
    _axis(c, f"{root}/platform/normal", p.distal_reach, 0x000000, op)
    c.set_transform(f"{root}/platform/normal", scene.transform(scene.align_y(n), np.zeros(3)))
    from spm_console.viewer.labels import TextSprite, label_transform  # meshcat: see view.py

    c.set_object(f"{root}/platform/label", TextSprite(look.label))
    c.set_transform(f"{root}/platform/label",
                    label_transform(n * p.distal_reach * look.label_reach, POSE_LABEL_M))


def build_scene(c: MeshcatClient, parts: scene.WristParts) -> None:
    """Send every part once (the server keeps them for browsers that connect later).
    Both wrists start hidden: nothing is known yet."""
    import meshcat.geometry as g

    from spm_console.viewer.labels import TextSprite, label_transform

    p = parts
    grey = g.MeshLambertMaterial(color=0x8C8C8C)
    base = g.TriangularMeshGeometry(p.base_points, np.array([[0, 1, 2], [0, 2, 1]]))
    c.set_object("base/plate", base, grey)
    centre = p.base_points.mean(0)
    for i in range(3):
        u = p.u[i]
        c.set_object(f"base/motor{i + 1}", g.Cylinder(0.04, radius=1.3 * p.delta), grey)
        c.set_transform(f"base/motor{i + 1}",
                        scene.transform(scene.align_y(u), p.base_points[i] + 0.02 * u))
        _axis(c, f"axes/u{i + 1}", p.proximal_reach, 0x333333)
        c.set_transform(f"axes/u{i + 1}", scene.transform(scene.align_y(u), np.zeros(3)))
        out = p.base_points[i] - centre
        where = p.base_points[i] + 0.8 * out - np.array([0.0, 0.0, 0.03])
        c.set_object(f"labels/leg{i + 1}", TextSprite(f"leg {i + 1}"))
        c.set_transform(f"labels/leg{i + 1}", label_transform(where, LEG_LABEL_M))
    c.set_object("labels/unknown", TextSprite("measured pose unknown"))
    c.set_transform("labels/unknown",
                    label_transform(centre - np.array([0.0, 0.0, 0.06]), CAPTION_M))
    for look in (MEASURED, TARGET):
        build_wrist(c, p, look)
        c.set_property(look.root, "visible", False)
    c.set_property("/Cameras/default/rotated/<object>", "position", list(CAMERA_POSITION))
    c.set_property("/Axes", "visible", False)  # the world axes are 0.5 m long: clutter
    c.set_property("/Background", "top_color", list(BACKGROUND[0]))
    c.set_property("/Background", "bottom_color", list(BACKGROUND[1]))


def draw_pose(c: MeshcatClient, look: Look, transforms: dict[str, F]) -> None:
    """Move one wrist's parts (``scene.pose_transforms``) under ``look.root``."""
    for name, T in transforms.items():
        c.set_transform(f"{look.root}/{name}", T)


def draw_path(c: MeshcatClient, normals: F, reach_m: float) -> None:
    """The path preview: the platform normal's tip along the path (normals (K, 3))."""
    import meshcat.geometry as g

    pts = scene.normal_tip_path(normals, reach_m)
    c.set_object("path/line", g.Line(g.PointsGeometry(pts), g.LineBasicMaterial(color=PATH_COLOR)))
    # WebGL draws lines one pixel wide whatever their linewidth: mark the samples too
    rgb = np.array([(PATH_COLOR >> k) & 255 for k in (16, 8, 0)], np.float32) / 255
    colors = np.repeat(rgb[:, None], pts.shape[1], axis=1)  # meshcat's points are vertex-coloured
    c.set_object("path/samples", g.PointsGeometry(pts, colors),
                 g.PointsMaterial(size=PATH_DOT_M, color=PATH_COLOR))
