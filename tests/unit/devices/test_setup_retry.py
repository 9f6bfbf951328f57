"""The bus's set-up retry (:meth:`DynamixelBus.set_up`): a transaction whose every try fails
says what went wrong first (a silent servo's timeout), not the last try's consequence of it
(a reply length still reserved for the first try's late reply), and how often it tried."""

from __future__ import annotations

import contextlib
from types import SimpleNamespace

import pytest

from spm_console.devices.base import CommError
from spm_console.devices.dynamixel.bus import SETUP_TIMEOUTS_S, _retry


def test_every_try_failing_reports_the_first_failure_and_the_tries() -> None:
    tries: list[float] = []
    transport = SimpleNamespace(patience=lambda t: (tries.append(t), contextlib.nullcontext())[1])
    drained: list[float] = []
    errors = iter(["no status packet within 4.0 ms (0 of 1 received, 0 corrupt)",
                   "a ping of id 2 not sent: id 2 did not answer a fence read either",
                   "a ping of id 2 not sent: id 2 did not answer a fence read either"])

    def fn() -> int:
        raise CommError(next(errors))

    with pytest.raises(CommError) as err:
        _retry(fn, transport, drained.append)  # type: ignore[arg-type]
    msg = str(err.value)
    assert msg.startswith("no status packet within 4.0 ms")
    assert "fence" not in msg and f"tried {len(SETUP_TIMEOUTS_S)} times" in msg
    assert tries == list(SETUP_TIMEOUTS_S) and len(drained) == len(SETUP_TIMEOUTS_S) - 1


def test_a_try_that_answers_ends_the_retry() -> None:
    transport = SimpleNamespace(patience=lambda _t: contextlib.nullcontext())
    calls = iter([CommError("lost"), 7])

    def fn() -> int:
        x = next(calls)
        if isinstance(x, CommError):
            raise x
        return x

    assert _retry(fn, transport, lambda _q: None) == 7  # type: ignore[arg-type]
