"""``--scheduler``: the address is asked by hand whether a Dask scheduler is there before Dask's
client connects; another service is refused (exit 4) within the probe's deadline, and Dask
never reads its bytes (it would allocate what they claim, or wait with no deadline)."""

from __future__ import annotations

import struct
from collections.abc import Callable
from pathlib import Path

import pytest

from spm_console.design import scheduler_probe
from spm_console.design.scheduler_probe import probe_scheduler
from spm_console.errors import BadInputError
from tests.support.fake_services import DASK_HANDSHAKE, tcp_service
from tests.unit.design.conftest import GRID

#: The probe's deadline in these tests, s: long enough for a loopback answer on a loaded host;
#: and the shorter one a service that says nothing is given (it is refused at the deadline).
DEADLINE_S = 2.0
SILENCE_S = 0.3


@pytest.mark.parametrize(("behaviour", "says"), [
    ("huge", "not a Dask scheduler"),
    ("random", "not a Dask scheduler"),
    ("hangup", "not a Dask scheduler"),
    ("echo", f"within {SILENCE_S:g} s"),
    ("silent", f"within {SILENCE_S:g} s"),
])
def test_a_service_that_is_not_dask_is_refused(behaviour: str, says: str) -> None:
    deadline = SILENCE_S if behaviour in ("echo", "silent") else DEADLINE_S
    with tcp_service(behaviour) as port, pytest.raises(BadInputError) as refused:
        probe_scheduler(f"tcp://127.0.0.1:{port}", timeout=deadline)
    assert refused.value.message.startswith(f"--scheduler tcp://127.0.0.1:{port}: ")
    assert says in refused.value.message


def test_a_first_message_longer_than_a_handshake_is_refused_unread(
        monkeypatch: pytest.MonkeyPatch) -> None:
    (length,) = struct.unpack("Q", DASK_HANDSHAKE[:8])
    monkeypatch.setattr(scheduler_probe, "MAX_HANDSHAKE_BYTES", length - 1)
    with tcp_service("dask") as port, pytest.raises(BadInputError, match=f"claims {length} bytes"):
        probe_scheduler(f"127.0.0.1:{port}", timeout=DEADLINE_S)


def test_a_scheduler_handshake_passes() -> None:
    with tcp_service("dask") as port:
        probe_scheduler(f"tcp://127.0.0.1:{port}", timeout=DEADLINE_S)
        probe_scheduler(f"127.0.0.1:{port}", timeout=DEADLINE_S)


def test_nothing_listening_is_refused() -> None:
    with tcp_service("silent") as port:
        pass  # closed again: nothing listens there now
    with pytest.raises(BadInputError, match="no Dask scheduler answered"):
        probe_scheduler(f"tcp://127.0.0.1:{port}", timeout=DEADLINE_S)


def test_a_sweep_on_a_service_that_is_not_dask_never_lets_dask_read_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
        write_spec: Callable[..., Path]) -> None:
    """Through the command: exit 4, the refusal on stderr, nothing of Dask's read."""
    from distributed.comm import tcp

    from spm_console.cli.main import main
    from spm_console.errors import ExitCode

    def read(*_a: object, **_k: object) -> object:
        raise AssertionError("Dask read the service's bytes")

    monkeypatch.setattr(tcp, "read_bytes_rw", read)
    monkeypatch.setattr(scheduler_probe, "PROBE_TIMEOUT_S", SILENCE_S)  # the echo says nothing
    spec = write_spec(GRID)
    for behaviour in ("huge", "random", "echo"):
        with tcp_service(behaviour) as port:
            rc = main(["design", "sweep", str(spec), "--out", str(tmp_path / behaviour),
                       "--scheduler", f"tcp://127.0.0.1:{port}"])
        err = capsys.readouterr().err
        assert rc == ExitCode.BAD_INPUT, err
        assert f"--scheduler tcp://127.0.0.1:{port}: " in err and "Traceback" not in err
