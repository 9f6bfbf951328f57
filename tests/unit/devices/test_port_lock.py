"""One owner per bus: a second opener of a port is refused (exit 4) naming the holder, and the
lock dies with its holder's descriptor."""

from __future__ import annotations

import os
import socket
from pathlib import Path

import pytest

from spm_console.devices.dynamixel import port_lock
from spm_console.devices.dynamixel.transport import UNIX_PREFIX, open_transport
from spm_console.errors import BadInputError, ExitCode


def test_a_second_lock_is_refused_naming_this_process(tmp_path: Path) -> None:
    path = str(tmp_path / "bus.lock")
    first = os.open(path, os.O_RDWR | os.O_CREAT)
    second = os.open(path, os.O_RDWR)
    try:
        port_lock.take(first, "PORT", path)
        with pytest.raises(BadInputError) as err:
            port_lock.take(second, "PORT", path)
        assert err.value.exit_code == ExitCode.BAD_INPUT
        assert f"the bus PORT is in use by process {os.getpid()} (" in err.value.message
        assert "nothing was sent" in err.value.message
        os.close(first)  # the holder goes: the lock with it
        first = -1
        port_lock.take(second, "PORT", path)
    finally:
        for fd in (first, second):
            if fd >= 0:
                os.close(fd)


def test_the_emulated_socket_has_one_owner(tmp_path: Path) -> None:
    path = str(tmp_path / "bus")
    server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    server.bind(path)
    server.listen(4)
    try:
        first = open_transport(UNIX_PREFIX + path)
        with pytest.raises(BadInputError, match="is in use by process"):
            open_transport(UNIX_PREFIX + path)
        shared = open_transport(UNIX_PREFIX + path, exclusive=False)  # the emulator's own tests
        shared.close()
        first.close()
        open_transport(UNIX_PREFIX + path).close()
    finally:
        server.close()


def test_a_holder_not_found_is_another_process(tmp_path: Path) -> None:
    path = tmp_path / "unlocked"
    path.write_text("")
    assert port_lock.holder_of(str(path)) == "another process"
    assert port_lock.holder_of(str(tmp_path / "missing")) == "another process"
