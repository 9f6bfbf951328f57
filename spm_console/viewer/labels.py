"""Text labels in the meshcat scene: camera-facing sprites carrying a text texture.

meshcat-python 0.3.2 has no text object, but the viewer page it serves turns a
texture of type ``"_text"`` into a canvas with that text drawn on it (black, centred,
the font shrunk until it fits the 256-pixel canvas). :class:`TextSprite` sends such a
texture on a three.js ``Sprite`` (always faces the camera; one world unit wide and
high, so its size is set by the scale of its transform: :func:`label_transform`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from meshcat.geometry import Object, SceneElement
from numpy.typing import NDArray

F = NDArray[np.float64]

#: Font size asked of the page, px of its 256-px canvas (shrunk if the text is wider).
FONT_PX = 56
#: Font family asked of the page.
FONT_FACE = "sans-serif"


class TextSprite(Object):
    """A camera-facing square with ``text`` drawn across its middle (black on clear)."""

    _type = "Sprite"

    def __init__(self, text: str, font_px: int = FONT_PX, opacity: float = 1.0) -> None:
        SceneElement.__init__(self)
        self.text = text
        self.font_px = font_px
        self.opacity = opacity
        self._material_uuid = SceneElement().uuid
        self._texture_uuid = SceneElement().uuid

    def lower(self) -> dict[str, Any]:
        return {
            "metadata": {"version": 4.5, "type": "Object"},
            "geometries": [],
            "textures": [{"uuid": self._texture_uuid, "type": "_text", "text": self.text,
                          "font_size": self.font_px, "font_face": FONT_FACE}],
            "materials": [{"uuid": self._material_uuid, "type": "SpriteMaterial",
                           "color": 0xFFFFFF, "map": self._texture_uuid, "transparent": True,
                           "opacity": self.opacity, "depthTest": False, "depthWrite": False}],
            "object": {"uuid": self.uuid, "type": "Sprite", "material": self._material_uuid,
                       "matrix": list(np.eye(4).flatten()), "renderOrder": 10},
        }


def label_transform(position_m: F, size_m: float) -> F:
    """Transform (4×4) placing a label's centre at ``position_m`` (m), ``size_m`` wide."""
    T = np.diag([size_m, size_m, size_m, 1.0])
    T[:3, 3] = np.asarray(position_m, float)
    return T
