"""The E-stop relay (commissioning's E-stop) reaches the motion process attached now and refuses every
stage after it."""

from __future__ import annotations

import pytest

from spm_console.errors import BusError
from spm_console.services.client import EstopRelay


class _Client:
    def __init__(self) -> None:
        self.estops: list[tuple[str, bool]] = []

    def estop(self, reason: str, by_signal: bool = False) -> None:
        self.estops.append((reason, by_signal))


def test_the_stop_reaches_the_attached_process_and_refuses_the_next_stage() -> None:
    stop = EstopRelay("commission")
    stop.check()  # not pressed: nothing refused
    first, second = _Client(), _Client()
    stop.attach(first)  # type: ignore[arg-type]
    assert stop.estop("operator E-stop (SPACE)") is True
    assert stop.estop("signal SIGTERM", True) is True  # sent again, the first reason kept
    assert first.estops == [("operator E-stop (SPACE)", False), ("signal SIGTERM", True)]
    stop.detach()
    with pytest.raises(BusError, match="commission stopped: operator E-stop"):
        stop.attach(second)  # type: ignore[arg-type]
    assert second.estops == []


def test_a_stop_between_stages_reaches_no_process_and_is_kept() -> None:
    stop = EstopRelay("commission")
    assert stop.estop("console closing")
    with pytest.raises(BusError, match="Nothing was written"):
        stop.check()
