"""One owner per serial bus: a second transport on a serial device (a pty stands for the
adapter) is refused before it sends anything, naming the holder."""

from __future__ import annotations

import os
import select

import pytest

from spm_console.devices.dynamixel.transport import SerialTransport
from spm_console.errors import BadInputError


def test_a_serial_device_has_one_owner() -> None:
    """A pty stands for the adapter: the second transport on it is refused before it sends,
    and the port is free again once the first closes."""
    master, slave = os.openpty()
    try:
        name = os.ttyname(slave)
        first = SerialTransport(name)
        with pytest.raises(BadInputError, match=f"in use by process {os.getpid()}"):
            SerialTransport(name)
        assert not _readable(master)  # nothing was written on the line
        first.close()
        SerialTransport(name).close()
        SerialTransport(name, exclusive=False).close()
    finally:
        os.close(master)
        os.close(slave)


def _readable(fd: int) -> bool:
    return bool(select.select([fd], [], [], 0)[0])
