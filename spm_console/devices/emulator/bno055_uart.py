"""The emulated BNO055's UART receiver: bytes in, reply frames out (Bosch BST-BNO055-DS000
§4.7). No I/O: ``devices/emulator/bno055.py`` serves it on a pseudo-terminal.

Behaviour where the datasheet names a status but not when it is sent (our choices):

- a byte that is not ``0xAA`` where a frame must start, or a second byte that is neither
  ``0x00`` (write) nor ``0x01`` (read), is answered ``EE 06`` (WRONG_START_BYTE);
- the header is checked as soon as its LEN byte is in (``header_status``): LEN 0 → ``EE 09``,
  LEN > 128 → ``EE 08``, bytes past address 0x7F → ``EE 04``; a write's data are not waited for;
- after such an error the receiver discards what follows until the line has been quiet for
  the character timeout (one reply per burst of garbage, never one per byte);
- a frame left incomplete for the character timeout (:data:`CHAR_TIMEOUT_S`, 20 ms: the
  datasheet gives no figure; 115200 baud moves a byte in 87 µs) is answered ``EE 0A``
  (RECEIVE_CHARACTER_TIMEOUT) and forgotten.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

from spm_console.devices.imu import bno055_protocol as bp

CHAR_TIMEOUT_S = 0.02
"""Longest pause between two bytes of one frame before it is abandoned, s."""


class Chip(Protocol):
    """What the receiver needs of the emulated chip: replies to whole requests, or None while
    it is silent (booting after a reset)."""

    def silent(self) -> bool: ...

    def read(self, reg: int, length: int) -> bytes | None: ...

    def write(self, reg: int, data: bytes) -> bytes | None: ...


class Bno055Uart:
    """Frames requests out of the byte stream and answers them through ``chip``.

    ``feed(data)`` takes the bytes that arrived now and returns the replies to send, in order;
    ``poll()`` returns the timeout reply of a frame left incomplete, once it is due
    (``deadline()`` says when). Also the endpoint's decoder (``pending``, ``skipped``,
    ``reset``)."""

    def __init__(self, chip: Chip, clock: Callable[[], float],
                 char_timeout_s: float = CHAR_TIMEOUT_S) -> None:
        if not 0.0 < char_timeout_s <= 1.0:
            raise ValueError(f"char_timeout_s must be within (0, 1] s, not {char_timeout_s}")
        self._chip = chip
        self._clock = clock
        self.char_timeout_s = char_timeout_s
        self._buf = bytearray()
        self._skipping = False
        self._last_rx = -math.inf
        self.skipped = 0
        """Bytes discarded: after an error, and while the chip was silent."""
        self.frames = 0
        """Whole requests answered by the chip."""
        self.errors = 0
        """Failures answered by the receiver itself (start byte, header, timeout)."""

    @property
    def pending(self) -> int:
        """Bytes of a frame not yet complete."""
        return len(self._buf)

    def reset(self) -> None:
        self._buf.clear()
        self._skipping = False

    def deadline(self) -> float | None:
        """When an incomplete frame times out (the clock's time), or None."""
        return self._last_rx + self.char_timeout_s if self._buf else None

    def poll(self, now: float | None = None) -> list[bytes]:
        """``[EE 0A]`` when the frame in progress has waited the character timeout, else []."""
        now = self._clock() if now is None else now
        if self._buf and now - self._last_rx >= self.char_timeout_s:
            self._buf.clear()
            self.errors += 1
            return [bp.status_reply(bp.Status.RECEIVE_CHARACTER_TIMEOUT)]
        return []

    def feed(self, data: bytes) -> list[bytes]:
        """The replies to what ``data`` (bytes that arrived now) completes."""
        now = self._clock()
        out = self.poll(now)
        if self._skipping and now - self._last_rx >= self.char_timeout_s:
            self._skipping = False
        self._last_rx = now
        if self._chip.silent():
            self._buf.clear()
            self.skipped += len(data)
            return out
        for b in data:
            reply = self._byte(b)
            if reply is not None:
                out.append(reply)
        return out

    def _fail(self, status: bp.Status) -> bytes:
        self._buf.clear()
        self._skipping = True
        self.errors += 1
        return bp.status_reply(status)

    def _byte(self, b: int) -> bytes | None:
        if self._skipping:
            self.skipped += 1
            return None
        buf = self._buf
        n = len(buf)
        if (n == 0 and b != bp.START) or (n == 1 and b not in (bp.READ, bp.WRITE)):
            return self._fail(bp.Status.WRONG_START_BYTE)
        buf.append(b)
        if n < 3:
            return None
        write, reg, length = buf[1] == bp.WRITE, buf[2], buf[3]
        if n == 3:
            status = bp.header_status(reg, length)
            if status is not None:
                return self._fail(status)
            if write:
                return None
            buf.clear()
            self.frames += 1
            return self._chip.read(reg, length)
        if len(buf) < 4 + length:
            return None
        data = bytes(buf[4:])
        buf.clear()
        self.frames += 1
        return self._chip.write(reg, data)
