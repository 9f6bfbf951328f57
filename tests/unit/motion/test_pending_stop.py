"""The E-stop the motion process holds (:class:`~spm_console.motion.stop_action.PendingStop`):
it reaches the motion it was meant for, whether it comes before that motion's executor exists
or while it runs; one that comes after that motion ended stops nothing, not even the next
motion; one sent between two motions stops the next."""

from __future__ import annotations

from spm_console.motion.stop_action import PendingStop


class Executor:
    """Records the E-stops it is asked for."""

    def __init__(self) -> None:
        self.asked: list[tuple[str, float | None, bool]] = []

    def request_estop(self, reason: str = "operator request", at_clock: float | None = None,
                      by_signal: bool = False) -> None:
        self.asked.append((reason, at_clock, by_signal))


def test_an_estop_before_the_executor_exists_reaches_it() -> None:
    stop = PendingStop()
    stop.begin(3)
    assert stop.request("SPACE", 1.5, False, after=0)
    ex = Executor()
    stop.attach(ex)
    assert ex.asked == [("SPACE", 1.5, False)]


def test_an_estop_during_the_motion_reaches_each_of_its_executors_with_the_first_reason() -> None:
    stop = PendingStop()
    stop.begin(1)
    homing = Executor()
    stop.attach(homing)
    assert stop.request("SPACE", 2.0, False, after=0)
    assert stop.request("signal SIGINT", 2.1, True, after=0)
    assert homing.asked == [("SPACE", 2.0, False)] * 2
    plan = Executor()
    stop.attach(plan)
    assert plan.asked == [("SPACE", 2.0, False)]


def test_an_estop_that_comes_after_its_motion_ended_stops_nothing_later() -> None:
    """The race of a run that ends as the operator presses SPACE: the E-stop for motion 4
    (sent while its result was on the way) arrives after it ended."""
    stop = PendingStop()
    stop.begin(4)
    stop.attach(Executor())
    stop.ended(4)
    assert not stop.request("SPACE", 3.0, False, after=0)
    assert stop.reason == ""
    stop.begin(6)
    nxt = Executor()
    stop.attach(nxt)
    assert nxt.asked == []


def test_an_estop_as_a_motion_closes_goes_with_it() -> None:
    """It came while the motion was still under way (its executor done): that motion's, and
    cleared with it."""
    stop = PendingStop()
    stop.begin(2)
    assert stop.request("SPACE", 3.0, False, after=1)
    stop.ended(2)
    stop.begin(5)
    nxt = Executor()
    stop.attach(nxt)
    assert nxt.asked == []
    assert stop.reason == ""


def test_an_estop_sent_between_two_motions_stops_the_next() -> None:
    """Its sender had motion 2's result: the E-stop is for a later motion (a front end marks
    the wrist moving before its request goes out, so the E-stop may arrive first)."""
    stop = PendingStop()
    stop.begin(2)
    stop.ended(2)
    assert stop.request("SPACE", 4.0, False, after=2)
    stop.begin(3)
    ex = Executor()
    stop.attach(ex)
    assert ex.asked == [("SPACE", 4.0, False)]


def test_this_process_own_estops_reach_only_a_motion_under_way() -> None:
    """A signal or the deadman between motions is not kept for the next one."""
    stop = PendingStop()
    assert not stop.request("signal SIGTERM to the motion process", by_signal=True)
    stop.begin(1)
    ex = Executor()
    stop.attach(ex)
    assert stop.request("client lost")
    assert ex.asked == [("client lost", None, False)]
    stop.ended(1)
    assert not stop.request("client lost")
