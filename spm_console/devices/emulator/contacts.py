"""What the emulated physical wrist tells about its legs' contacts, in a module light enough
for the process that owns the emulator's child (no MuJoCo): :class:`Collision` and its JSON
form on the child's stdout."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

#: Segment names a contact can name (each leg's proximal and distal link).
_MAX_SEGMENT_CHARS = 8


@dataclass(frozen=True)
class Collision:
    """Two legs' envelope capsules met (their segments closer than 2δ)."""

    t: float
    """Simulated time, s (the emulator's clock)."""
    legs: tuple[int, int]
    """Legs 0..2."""
    segments: tuple[str, str]
    """The segment of each leg, e.g. ("DE", "EF")."""
    distance_mm: float
    """Signed distance between the capsules' surfaces, mm (< 0: they overlap)."""
    theta_deg: tuple[float, float, float]
    """The joint angles then, deg."""

    @classmethod
    def from_json(cls, d: Mapping[str, object]) -> Collision:
        """From its JSON form (:func:`dataclasses.asdict`, as the child writes it); ValueError
        when ``d`` is not one (other keys, types, legs outside 0..2, non-finite numbers)."""
        if set(d) != {"t", "legs", "segments", "distance_mm", "theta_deg"}:
            raise ValueError(f"a contact with keys {sorted(d)}")
        legs = [_leg(k) for k in _items(d["legs"], 2)]
        segs = [_segment(s) for s in _items(d["segments"], 2)]
        th = [_number(x) for x in _items(d["theta_deg"], 3)]
        return cls(_number(d["t"]), (legs[0], legs[1]), (segs[0], segs[1]),
                   _number(d["distance_mm"]), (th[0], th[1], th[2]))


def _items(x: object, n: int) -> list[object]:
    if not isinstance(x, list) or len(x) != n:
        raise ValueError(f"a contact's field is not a list of {n}: {x!r:.80}")
    return x


def _number(x: object) -> float:
    if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
        raise ValueError(f"a contact's number is not finite: {x!r:.80}")
    return float(x)


def _leg(x: object) -> int:
    if isinstance(x, bool) or not isinstance(x, int) or not 0 <= x <= 2:
        raise ValueError(f"a contact's leg is not 0..2: {x!r:.80}")
    return x


def _segment(x: object) -> str:
    if not isinstance(x, str) or not 0 < len(x) <= _MAX_SEGMENT_CHARS:
        raise ValueError(f"a contact's segment is not a short name: {x!r:.80}")
    return x
