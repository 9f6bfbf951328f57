"""The IMU stage's horn offsets move the zero it ran on, its fraction of a tick included (a
zero at rest has one; a jig's has none): true θ = θ read + δ, so the zero moves by −d·δ ticks."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from spm_console.config.schema import Profile
from spm_console.services.commissioning.leg_map import LegMatch
from spm_console.services.commissioning.stages import Commissioned, Discovery, refined


@pytest.mark.parametrize("trims", [(0.0, 0.0, 0.0), (0.31, -0.27, 0.05)])
def test_the_horns_move_the_zero_the_stage_ran_on(agile: Profile,
                                                   trims: tuple[float, float, float]) -> None:
    joints = agile.bus.joints
    legs = tuple(LegMatch(j.id, k + 1, j.direction, 0.0, 0.0, 0.0)
                 for k, j in enumerate(joints))
    offsets = (joints[0].tick_offset, joints[1].tick_offset, joints[2].tick_offset)
    before = Commissioned(Discovery("2.0", (), (1, 2, 3)), (legs[0], legs[1], legs[2]), None,
                          offsets, agile, tick_trims=trims)
    horn = (0.5, -0.25, 0.07)
    stage = SimpleNamespace(horn_deg=horn, arcs_deg=None, payload=None)
    after = refined(before, stage)  # type: ignore[arg-type]
    tpd = agile.bus.ticks_per_turn / 360.0
    assert after.tick_offsets is not None
    for k, m in enumerate(legs):
        was = offsets[k] + trims[k]
        now = after.tick_offsets[k] + after.tick_trims[k]
        assert now == pytest.approx(was - m.direction * horn[k] * tpd, abs=1e-3)
        assert abs(after.tick_trims[k]) <= 0.5
