"""The unique FK's continuation is never asked to walk an unbounded distance: a target not
finite, or farther than two turns from its start, is refused before the first step."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spm_console.core.kinematics import model as model_module
from spm_console.core.kinematics.model import MAX_TRACK_RAD, SpmModel

#: More continuation steps than any test here needs (the good row is a degree from home).
STEP_BUDGET = 50


@pytest.fixture
def counted_steps(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The continuation steps taken; one beyond :data:`STEP_BUDGET` fails the test at once
    (instead of walking for hours)."""
    calls: list[int] = []
    real = model_module.continuation_step

    def step(*a: object, **k: object) -> object:
        calls.append(1)
        if len(calls) > STEP_BUDGET:
            raise AssertionError("the continuation walks an unbounded distance")
        return real(*a, **k)  # type: ignore[arg-type]

    monkeypatch.setattr(model_module, "continuation_step", step)
    return calls


@pytest.mark.parametrize("bad_deg", [1e10, 1e308, -1e308, math.nan, math.inf, 1000.0])
def test_a_far_or_non_finite_target_is_refused_unwalked(
        agile_model: SpmModel, counted_steps: list[int], bad_deg: float) -> None:
    home = agile_model.theta_home
    good = home + math.radians(1.0)
    bad = home.copy()
    bad[1] = math.radians(bad_deg)
    far, near = agile_model.track_batch(np.stack([bad, good]))
    assert near.ok
    assert not far.ok and "not a motion to follow" in far.reason
    assert far.pose is not None and np.allclose(far.pose.theta, home)  # where it started
    assert len(counted_steps) <= STEP_BUDGET


def test_the_bound_is_two_turns_from_the_start(agile_model: SpmModel,
                                               counted_steps: list[int]) -> None:
    start = agile_model.theta_home
    beyond = start + np.array([0.0, MAX_TRACK_RAD * 1.001, 0.0])
    (r,) = agile_model.track_batch(beyond[None], start, np.eye(3), max_step=1.0)
    assert not r.ok and "not a motion to follow" in r.reason and not counted_steps
