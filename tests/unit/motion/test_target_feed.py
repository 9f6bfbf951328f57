"""The live target feed's deadman, on a fake clock (seconds): it counts the source's silence
from the start of following, not from the feed's creation."""

from __future__ import annotations

import numpy as np

from spm_console.motion.follow.target_feed import TargetFeed


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_the_deadman_counts_from_the_start_of_following() -> None:
    clock = Clock()
    home, new, wrist = np.zeros(3), np.array([4.0, -3.0, 2.0]), np.array([1.0, 1.0, 1.0])
    feed = TargetFeed(initial_deg=home, deadman_s=0.4, clock=clock)
    clock.t += 2.0  # homing, the regions, the first solve: longer than the deadman
    assert not feed.targets(0.0, 0.02, 1, home)[1]  # not armed: never a hold
    feed.arm()
    clock.t += 0.3
    targets, held = feed.targets(0.0, 0.02, 2, wrist)
    assert not held and feed.deadman_trips == 0
    np.testing.assert_array_equal(targets, [home, home])
    clock.t += 0.2  # 0.5 s of silence since the start: hold where the wrist is
    targets, held = feed.targets(0.0, 0.02, 2, wrist)
    assert held and feed.deadman_trips == 1
    np.testing.assert_array_equal(targets[0], wrist)
    feed.set(new)  # updates resume: followed again
    targets, held = feed.targets(0.0, 0.02, 2, wrist)
    assert not held and feed.deadman_trips == 1
    np.testing.assert_array_equal(targets[0], new)


def test_an_update_after_arming_counts_from_itself() -> None:
    clock = Clock()
    feed = TargetFeed(initial_deg=np.zeros(3), deadman_s=0.4, clock=clock)
    feed.arm()
    clock.t += 0.3
    feed.set(np.ones(3))
    clock.t += 0.3  # 0.6 s since the start, 0.3 s since the update
    assert not feed.targets(0.0, 0.02, 1, np.zeros(3))[1]
    clock.t += 0.15  # 0.45 s since the update
    assert feed.targets(0.0, 0.02, 1, np.zeros(3))[1]
