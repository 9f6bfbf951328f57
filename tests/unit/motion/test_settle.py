"""The settling law at the goal (motion/settle.py) against a servo that stops off its goal:
a P-only loop with friction, modelled as a dead band and the links' weight as a bias, read
through the encoder's ticks."""

from __future__ import annotations

import numpy as np

from spm_console.config.schema import Settle
from spm_console.motion.goals.settle import SETTLED_PERIODS, Settling, settle_periods

TICK = 360.0 / 4096


class StickyServo:
    """At rest the shaft moves only when the goal sent is farther than ``band`` from it, and
    then stops ``band`` short on the side it came from, plus a constant ``bias`` (weight)."""

    def __init__(self, start: np.ndarray, band: float, bias: np.ndarray) -> None:
        self.pos = np.asarray(start, float)
        self.band = band
        self.bias = bias

    def step(self, goal: np.ndarray) -> np.ndarray:
        target = goal + self.bias
        gap = target - self.pos
        moving = np.abs(gap) > self.band
        self.pos = np.where(moving, target - np.sign(gap) * self.band, self.pos)
        return np.round(self.pos / TICK) * TICK  # what the encoder reads


def _run(s: Settling, servo: StickyServo, periods: int) -> tuple[int, np.ndarray]:
    for k in range(periods):
        read = servo.step(s.reference)
        s.update(read)
        if s.settled:
            return k + 1, read
    return periods, read


def test_the_offset_is_taken_up_within_the_tolerance() -> None:
    goal = np.array([66.8, 155.0, 131.48])
    law = Settle(duration_s=1.0, max_correction_deg=0.5, tolerance_deg=0.1)
    servo = StickyServo(goal + np.array([0.2, 0.25, -0.3]), band=2 * TICK,
                        bias=np.array([0.0, 0.2, -0.1]))
    s = Settling(law, goal, lambda theta: True)
    periods, read = _run(s, servo, settle_periods(law, 0.02))
    assert s.settled and periods <= 30
    assert np.abs(read - goal).max() <= 0.1
    assert np.abs(s.shift).max() <= 0.5 and s.refused == 0
    assert s.within == SETTLED_PERIODS


def test_the_shift_is_bounded() -> None:
    goal = np.array([66.8, 155.0, 131.48])
    law = Settle(duration_s=1.0, max_correction_deg=0.3, tolerance_deg=0.1)
    # the weight pulls joint 2 by 1°: more than the shift may take up
    servo = StickyServo(goal, band=0.0, bias=np.array([0.0, 1.0, 0.0]))
    s = Settling(law, goal, lambda theta: True)
    periods, read = _run(s, servo, settle_periods(law, 0.02))
    assert not s.settled and periods == 50
    assert np.isclose(s.shift[1], -0.3)  # at its bound; the rest of the offset stays
    assert np.isclose(read[1] - goal[1], 0.7, atol=TICK)


def test_a_goal_not_allowed_is_never_sent() -> None:
    goal = np.array([66.8, 155.0, 131.48])
    law = Settle(duration_s=1.0, max_correction_deg=0.5, tolerance_deg=0.1)
    servo = StickyServo(goal, band=0.0, bias=np.array([0.0, 0.4, 0.0]))

    def allowed(theta: np.ndarray) -> bool:  # joint 2 no lower than 154.9 (a face of P′)
        return bool(theta[1] >= 154.9)

    s = Settling(law, goal, allowed)
    sent = []
    for _ in range(settle_periods(law, 0.02)):
        sent.append(s.reference.copy())
        s.update(servo.step(s.reference))
    assert all(allowed(t) for t in sent)
    assert s.refused > 0 and not s.settled


def test_a_lost_read_changes_nothing() -> None:
    goal = np.zeros(3)
    s = Settling(Settle(duration_s=1.0), goal, lambda theta: True)
    s.update(None)
    s.update(np.array([np.nan, 0.0, 0.0]))
    assert np.array_equal(s.shift, np.zeros(3)) and s.within == 0
    s.update(np.array([0.3, 0.0, 0.0]))
    assert np.isclose(s.shift[0], -0.3 * 0.3)


def test_a_refused_shift_keeps_the_previous_one() -> None:
    goal = np.array([10.0, 20.0, 30.0])
    s = Settling(Settle(duration_s=1.0), goal, lambda theta: False)
    s.update(goal + 0.5)
    assert np.array_equal(s.reference, goal) and s.refused == 1


def test_a_joint_at_a_face_leaves_the_others_free_to_settle() -> None:
    """The goal on the grid's 155° face: joint 2 rests below it and may not be sent past it,
    joints 1 and 3 still take their offsets up."""
    goal = np.array([66.8, 155.0, 131.48])
    law = Settle(duration_s=1.0, max_correction_deg=0.5, tolerance_deg=0.1)
    servo = StickyServo(goal, band=0.0, bias=np.array([-0.3, -0.2, 0.25]))

    def allowed(theta: np.ndarray) -> bool:
        return bool(theta[1] <= 155.0)

    s = Settling(law, goal, allowed)
    sent = []
    for _ in range(settle_periods(law, 0.02)):
        sent.append(s.reference.copy())
        read = servo.step(s.reference)
        s.update(read)
    assert all(allowed(t) for t in sent) and s.refused > 0
    # within the tolerance a joint keeps its shift (moving it would only move it out)
    assert abs(read[0] - goal[0]) <= law.tolerance_deg
    assert abs(read[2] - goal[2]) <= law.tolerance_deg
    assert s.shift[1] == 0.0 and np.isclose(read[1] - goal[1], -0.2, atol=TICK)


def test_a_run_that_did_not_settle_says_which_joint_rests_how_far_and_why() -> None:
    """What execute and the Execute step print under the final θ (the event alone was in the
    log: a run at a goal on the certified set's face read as plainly completed)."""
    from spm_console.motion.stats import SettleOutcome

    done = SettleOutcome(True, (0.01, -0.02, 0.0), 0.05, 2.0, 0)
    assert done.text() == ""
    short = SettleOutcome(False, (0.0005, 0.174, -0.042), 0.05, 2.0, 100)
    text = short.text()
    assert text.startswith("did not settle within 2 s: joint 2 rests 0.17° from its goal")
    assert "100 goal shifts refused" in text and "certified set" in text
    assert "refused" not in SettleOutcome(False, (0.0, 0.0, -0.3), 0.05, 2.0, 0).text()
    assert "joint 3 rests 0.30°" in SettleOutcome(False, (0.0, 0.0, -0.3), 0.05, 2.0, 0).text()
    assert short.to_dict() == {"settled": False, "error_deg": [0.0005, 0.174, -0.042],
                               "tolerance_deg": 0.05, "duration_s": 2.0, "refused_shifts": 100}


class LaggyServo(StickyServo):
    """A :class:`StickyServo` that acts on the goal sent ``lag`` periods before."""

    def __init__(self, start: np.ndarray, band: float, bias: np.ndarray, lag: int) -> None:
        super().__init__(start, band, bias)
        self.sent = [np.asarray(start, float)] * lag

    def step(self, goal: np.ndarray) -> np.ndarray:
        self.sent.append(np.asarray(goal, float))
        return super().step(self.sent.pop(0))


def test_a_tolerance_under_a_tick_settles_with_friction_and_lag() -> None:
    """A commissioned profile's tolerance (0.05°: one encoder tick fits the window, or none
    on a joint, then two ticks around it) against servos with friction (a dead band up to
    0.12°), a bias and a response a few periods late: every joint settles. A fixed gain
    hunted across the window until the time ran out in about one case in four."""
    rng = np.random.default_rng(7)
    law = Settle(duration_s=2.0, max_correction_deg=0.5, tolerance_deg=0.05)
    for _ in range(50):
        goal = rng.uniform(60.0, 150.0, 3)
        servo = LaggyServo(goal + rng.uniform(-0.3, 0.3, 3), float(rng.uniform(0.03, 0.12)),
                           rng.uniform(-0.3, 0.3, 3), int(rng.integers(1, 5)))
        s = Settling(law, goal, lambda theta: True)
        periods, read = _run(s, servo, settle_periods(law, 0.02))
        assert s.settled, (periods, read - goal, s.gain)
        assert np.abs(read - goal).max() <= law.tolerance_deg
