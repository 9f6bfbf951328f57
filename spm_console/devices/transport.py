"""Serial transport: a pyserial port, short reply timeouts, one transaction at a time.

``transact(packet, decoder, count)`` flushes stale input, writes one instruction
packet and collects ``count`` decoded packets, each within ``timeout_s`` of the
previous one (so a sync read of three servos waits at most 3 × timeout). The wait
sleeps in ``select`` on the port's file descriptor (no busy loop). A lock makes
transactions atomic when a UI thread and the executor share the bus. Low-latency
mode (FTDI/U2D2) is requested best-effort; it raises on a pty and is skipped.

Limits, stated plainly: Dynamixel status packets carry no sequence number. Input
is flushed before each instruction, so replies that arrive late are discarded, but
a complete set of replies delayed by almost exactly the time between two
transactions would be taken for the current one. The executor's model-prediction
check is the guard against such stale data.
"""

from __future__ import annotations

import contextlib
import select
import threading
import time
from typing import Protocol, TypeVar

import serial

from spm_console.devices.base import CommError
from spm_console.errors import BusError

P = TypeVar("P")


class StreamDecoder(Protocol[P]):
    """What transact() needs from Decoder1 / Decoder2."""

    rejected: int

    def feed(self, data: bytes) -> list[P]: ...

    def reset(self) -> None: ...


class SerialTransport:
    """One open serial port (real adapter or the emulator's pty)."""

    def __init__(self, port: str, baud: int = 1_000_000, timeout_s: float = 0.004) -> None:
        if not port:
            raise BusError("no serial port given (profile bus.port is empty): pass --port DEV "
                           "or use the emulated bus (--sim)")
        try:
            self._ser = serial.Serial(port=port, baudrate=baud, timeout=0, write_timeout=1.0)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise BusError(f"cannot open serial port {port}: {exc}. Check the device path, "
                           "that the adapter is plugged in and that you are in the 'dialout' "
                           "group") from None
        self.port = port
        self.timeout_s = timeout_s
        self.low_latency = False
        try:
            self._ser.set_low_latency_mode(True)
            self.low_latency = True
        except (AttributeError, NotImplementedError, ValueError, OSError, serial.SerialException):
            pass  # a pty or an adapter without ASYNC_LOW_LATENCY: best effort only
        self._lock = threading.Lock()
        self.bytes_out = 0
        self.bytes_in = 0

    @property
    def lock(self) -> threading.Lock:
        return self._lock

    def close(self) -> None:
        with contextlib.suppress(serial.SerialException, OSError):
            self._ser.close()

    def _send(self, packet: bytes) -> None:
        try:
            self._ser.reset_input_buffer()
            self._ser.write(packet)
        except (serial.SerialException, OSError) as exc:
            raise CommError(f"write to {self.port} failed: {exc}") from None
        self.bytes_out += len(packet)

    def transact(self, packet: bytes, decoder: StreamDecoder[P], count: int,
                 timeout_s: float | None = None) -> list[P]:
        """Send ``packet`` and return the next ``count`` packets (CommError on timeout)."""
        with self._lock:
            decoder.reset()
            self._send(packet)
            return self._collect(decoder, count, timeout_s or self.timeout_s) if count else []

    def send(self, packet: bytes) -> None:
        """Send a packet that gets no reply (broadcast sync write)."""
        with self._lock:
            self._send(packet)

    def drain(self, quiet_s: float, max_s: float = 0.25) -> int:
        """Discard input until the line has been quiet for ``quiet_s`` (at most ``max_s``).

        For set-up retries after a lost reply: late replies to the failed request are
        still on their way and would otherwise be taken for the next request's. Returns
        the number of bytes discarded. Not for the real-time loop (it waits).
        """
        dropped = 0
        with self._lock:
            fd = self._ser.fileno()
            end = time.perf_counter() + max_s
            while (left := end - time.perf_counter()) > 0:
                try:
                    ready, _, _ = select.select([fd], [], [], min(quiet_s, left))
                    if not ready:
                        break
                    dropped += len(self._ser.read(self._ser.in_waiting or 1))
                except (serial.SerialException, OSError) as exc:
                    raise CommError(f"read from {self.port} failed: {exc}") from None
        self.bytes_in += dropped
        return dropped

    def _collect(self, decoder: StreamDecoder[P], count: int, timeout_s: float) -> list[P]:
        got: list[P] = []
        fd = self._ser.fileno()
        deadline = time.perf_counter() + timeout_s
        while len(got) < count:
            remaining = deadline - time.perf_counter()
            if remaining <= 0:
                raise CommError(
                    f"no status packet within {timeout_s * 1e3:.1f} ms "
                    f"({len(got)} of {count} received, {decoder.rejected} corrupt)"
                )
            try:
                ready, _, _ = select.select([fd], [], [], remaining)
                if not ready:
                    continue
                data = self._ser.read(self._ser.in_waiting or 1)
            except (serial.SerialException, OSError) as exc:
                raise CommError(f"read from {self.port} failed: {exc}") from None
            self.bytes_in += len(data)
            new = decoder.feed(data)
            if new:
                got.extend(new)
                deadline = time.perf_counter() + timeout_s
        return got
