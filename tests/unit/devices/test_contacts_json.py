"""A leg contact crosses from the emulator's child as JSON and comes back the same typed
object; anything else on that pipe is refused (ValueError), never read by key."""

from __future__ import annotations

import json
from dataclasses import asdict

import pytest

from spm_console.devices.emulator.contacts import Collision

HIT = Collision(1.25, (0, 2), ("DE", "EF"), -3.5, (118.2, 62.0, 63.7))


def test_a_contact_round_trips_through_its_json() -> None:
    assert Collision.from_json(json.loads(json.dumps(asdict(HIT)))) == HIT


@pytest.mark.parametrize("bad", [
    {},
    {**asdict(HIT), "extra": 1},
    {k: v for k, v in asdict(HIT).items() if k != "t"},
    {**asdict(HIT), "t": "1.0"},
    {**asdict(HIT), "t": float("nan")},
    {**asdict(HIT), "legs": [0, 3]},
    {**asdict(HIT), "legs": [True, 1]},
    {**asdict(HIT), "legs": [0]},
    {**asdict(HIT), "segments": ["DE", ""]},
    {**asdict(HIT), "segments": ["DE", "x" * 100]},
    {**asdict(HIT), "theta_deg": [1.0, 2.0]},
    {**asdict(HIT), "theta_deg": [1.0, 2.0, float("inf")]},
    {**asdict(HIT), "distance_mm": None},
])
def test_anything_else_is_refused(bad: dict[str, object]) -> None:
    d = json.loads(json.dumps(bad, allow_nan=True))
    with pytest.raises(ValueError, match="contact"):
        Collision.from_json(d)
