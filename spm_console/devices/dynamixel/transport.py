"""Bus transport: short reply timeouts, one transaction at a time, over a serial port
(pyserial: a real adapter or the emulator's pty) or a Unix-domain socket (the emulated
bus's default link, port ``unix:PATH``; see :func:`open_transport`).

``transact(packet, decoder, count, check=…)`` discards the input already waiting
(counted in ``bytes_flushed``; ``on_late`` may look at it first), writes one instruction packet and collects
``count`` decoded packets, each within ``timeout_s`` of the previous one (so a sync
read of three servos waits at most 3 × timeout); when the time is up the
transaction has failed, whatever arrives afterwards. ``check`` sees every decoded
packet as it arrives and says how many of the expected replies it settles: a
packet that answers nothing of this request is set aside and does not extend the
wait. The wait sleeps in ``select`` on the port's file descriptor (no busy loop).
A re-entrant lock makes transactions atomic when a UI thread and the executor
share the bus (the link holds it around its bookkeeping too). Low-latency mode
(FTDI/U2D2) is requested best-effort; it raises on a pty and is skipped.

Limits, stated plainly: Dynamixel status packets carry no sequence number, and
flushing removes only the replies that arrived before the request went out, so the
transport alone cannot tell a late reply from a current one. The link decides
(``devices/dynamixel/link.py`` with ``devices/dynamixel/reply_ledger.py``): requests that may still be
answered get distinct reply lengths, and a packet is accepted only as the answer
to the request it matches. Guaranteed: a status packet taken as the answer to a
request is never the reply to another request sent within ``REPLY_HORIZON_S``
(1.5 s) before it; a late reply fails the transaction it lands in and is counted
(``stale_replies``) — provided each servo answers its requests in order and with
the length asked for, as the protocol specifies. Not guaranteed: a reply more than
1.5 s late can be taken for a request of the same length to the same servo that
is then in flight; and "late" is judged by this process's clock, so a reply landing
just after the timeout, while the process was not scheduled, may still be read in
time (it is then the current request's own reply, never another's).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import select
import socket
import struct
import termios
import threading
import time
from collections.abc import Callable, Iterator
from typing import Protocol, TypeVar

import serial

from spm_console.devices.base import CommError
from spm_console.devices.dynamixel import port_lock
from spm_console.errors import BadInputError, BusError
from spm_console.system.simclock import CATCH_UP_S, SimClock

P = TypeVar("P")

#: Port prefix of a Unix-domain socket bus (the emulated bus's default link).
UNIX_PREFIX = "unix:"


class StreamDecoder(Protocol[P]):
    """What transact() needs from Decoder1 / Decoder2."""

    rejected: int

    def feed(self, data: bytes) -> list[P]: ...

    def reset(self) -> None: ...


class Transport:
    """One open bus link: transactions, sends and drains over a byte stream. Subclasses give
    the stream (:class:`SerialTransport`, :class:`SocketTransport`)."""

    def __init__(self, port: str, timeout_s: float) -> None:
        self.port = port
        self.timeout_s = timeout_s
        self.low_latency = False
        """The serial adapter's low-latency mode was granted (never for a pty or a socket)."""
        self._lock = threading.RLock()
        self.bytes_out = 0
        self.bytes_in = 0
        self.bytes_flushed = 0
        """Input discarded unread before a request (replies that came too late)."""
        self.sim: SimClock | None = None
        """Simulated time (an emulated bus in lockstep, :meth:`simulate`); None: the wall
        clock."""
        self._byte_s = 0.0

    def simulate(self, clock: SimClock, baud: int) -> None:
        """Wait on ``clock``'s simulated time from now on: each reply within the timeout in
        simulated seconds, each transaction taking its bytes' time on the wire at ``baud``
        (10 bits a byte)."""
        self.sim = clock
        self._byte_s = 10.0 / baud

    # --- the byte stream (OSError on failure) --------------------------------------

    def fileno(self) -> int:
        raise NotImplementedError

    def _waiting(self) -> int:
        """Bytes ready to read now."""
        raise NotImplementedError

    def _read(self, n: int) -> bytes:
        """Up to ``n`` bytes that are ready (at least one when select said so)."""
        raise NotImplementedError

    def _write(self, data: bytes) -> None:
        raise NotImplementedError

    def _discard_input(self) -> None:
        raise NotImplementedError

    def _close(self) -> None:
        raise NotImplementedError

    # --- transactions ---------------------------------------------------------------

    @property
    def lock(self) -> threading.RLock:
        """Held during a transaction; re-entrant, so a caller can hold it across its own
        bookkeeping and the transaction."""
        return self._lock

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self._close()

    def _send(self, packet: bytes, on_late: Callable[[bytes], object] | None = None) -> None:
        try:
            if self.sim is not None:  # the emulator's replies due by now are all here
                self.sim.catch_up()
            waiting = self._waiting()
            if waiting and on_late is not None:  # came after the last transaction: late
                late = self._read(waiting)
                self.bytes_flushed += len(late)
                on_late(late)
            elif waiting:
                self.bytes_flushed += waiting
            self._discard_input()
            self._write(packet)
        except OSError as exc:  # serial.SerialException is an OSError
            raise CommError(f"write to {self.port} failed: {exc}") from None
        self.bytes_out += len(packet)
        if self.sim is not None:
            self.sim.sent(len(packet))

    @contextlib.contextmanager
    def patience(self, timeout_s: float) -> Iterator[None]:
        """Within the block, wait at least ``timeout_s`` for each reply (set-up retries: a
        servo or an emulated bus slow to answer once is not absent). Holds the lock."""
        with self._lock:
            before = self.timeout_s
            self.timeout_s = max(before, timeout_s)
            try:
                yield
            finally:
                self.timeout_s = before

    def transact(self, packet: bytes, decoder: StreamDecoder[P], count: int,
                 timeout_s: float | None = None,
                 check: Callable[[P], int] | None = None,
                 on_late: Callable[[bytes], object] | None = None) -> list[P]:
        """Send ``packet`` and return the next ``count`` packets (CommError on timeout).

        ``check(packet)`` is called for each packet as it is decoded and says how many of
        the ``count`` expected replies it settles: 0 for a packet that does not answer
        this request (it is left out and does not extend the wait), more than 1 when it
        shows that earlier expected replies will not come. Without ``check`` every
        packet settles one. ``on_late(bytes)`` receives the input found waiting before
        the request is sent (it is discarded either way)."""
        with self._lock:
            decoder.reset()
            self._send(packet, on_late)
            if not count:
                self._on_wire(len(packet))
                return []
            if self.sim is not None:
                return self._collect_sim(self.sim, len(packet), decoder, count,
                                         timeout_s or self.timeout_s, check)
            return self._collect(decoder, count, timeout_s or self.timeout_s, check)

    def send(self, packet: bytes, on_late: Callable[[bytes], object] | None = None) -> None:
        """Send a packet that gets no reply (broadcast sync write); ``on_late`` as in
        :meth:`transact`."""
        with self._lock:
            self._send(packet, on_late)
            self._on_wire(len(packet))

    def _on_wire(self, n: int) -> None:
        """In simulated time: ``n`` bytes took their time on the wire (once the emulator has
        taken them, at the instant they were sent)."""
        if self.sim is not None:
            self.sim.advance_to(self.sim.now() + n * self._byte_s)

    def drain(self, quiet_s: float, max_s: float = 0.25,
              on_late: Callable[[bytes], object] | None = None) -> int:
        """Discard input until the line has been quiet for ``quiet_s`` (at most ``max_s``).

        For set-up retries after a lost reply: the late replies to the failed request
        are let in and thrown away before the next one (``on_late`` sees them first).
        Returns the number of bytes discarded. Not for the real-time loop (it waits).
        """
        chunks: list[bytes] = []
        with self._lock:
            fd = self.fileno()
            if self.sim is not None:  # what the emulator holds back comes when it is due
                sim = self.sim
                sim.catch_up()
                sim.advance_to(sim.due if sim.due <= sim.now() + max_s else sim.now() + quiet_s)
            end = time.perf_counter() + max_s
            while (left := end - time.perf_counter()) > 0:
                try:
                    ready, _, _ = select.select([fd], [], [], min(quiet_s, left))
                    if not ready:
                        break
                    chunks.append(self._read(self._waiting() or 1))
                except OSError as exc:
                    raise CommError(f"read from {self.port} failed: {exc}") from None
            data = b"".join(chunks)
            if data and on_late is not None:
                on_late(data)
        self.bytes_in += len(data)
        return len(data)

    def _collect_sim(self, sim: SimClock, sent: int, decoder: StreamDecoder[P], count: int,
                     timeout_s: float, check: Callable[[P], int] | None) -> list[P]:
        """:meth:`_collect` in simulated time: once the emulator has answered the request
        (:meth:`SimClock.catch_up`), what it wrote is there to read; a reply it holds back
        (a delay fault) comes when the clock reaches it, within the timeout, or the
        transaction fails with the clock at the timeout. The transaction then took its bytes'
        time on the wire."""
        got: list[P] = []
        settled = 0
        received = 0
        fd = self.fileno()
        deadline = sim.now() + timeout_s
        while settled < count:
            try:
                if not select.select([fd], [], [], 0)[0]:
                    if not sim.catch_up():
                        raise CommError(f"the emulated bus did not answer {self.port} "
                                        "(simulated time)")
                    if not select.select([fd], [], [], 0)[0]:
                        if sim.due > deadline:
                            sim.advance_to(deadline)
                            raise CommError(
                                f"no status packet within {timeout_s * 1e3:.1f} ms of simulated "
                                f"time ({len(got)} of {count} received, {decoder.rejected} "
                                "corrupt)")
                        sim.advance_to(sim.due)
                        sim.catch_up()
                        if not select.select([fd], [], [], CATCH_UP_S)[0]:
                            raise CommError(f"the emulated bus did not send its reply on "
                                            f"{self.port} (simulated time)")
                data = self._read(self._waiting() or 1)
            except OSError as exc:
                raise CommError(f"read from {self.port} failed: {exc}") from None
            received += len(data)
            if (n := self._settle(decoder, data, check, got)) > 0:
                settled += n
                deadline = sim.now() + timeout_s
        self._on_wire(sent + received)
        return got

    def _collect(self, decoder: StreamDecoder[P], count: int, timeout_s: float,
                 check: Callable[[P], int] | None) -> list[P]:
        got: list[P] = []
        settled = 0
        fd = self.fileno()
        deadline = time.perf_counter() + timeout_s
        while settled < count:
            remaining = deadline - time.perf_counter()
            if remaining <= 0:  # what arrives from now on is late, even if it is there
                raise CommError(f"no status packet within {timeout_s * 1e3:.1f} ms "
                                f"({len(got)} of {count} received, {decoder.rejected} corrupt)")
            try:
                ready, _, _ = select.select([fd], [], [], remaining)
                if not ready:
                    continue
                data = self._read(self._waiting() or 1)
            except OSError as exc:
                raise CommError(f"read from {self.port} failed: {exc}") from None
            if (n := self._settle(decoder, data, check, got)) > 0:
                settled += n
                deadline = time.perf_counter() + timeout_s
        return got

    def _settle(self, decoder: StreamDecoder[P], data: bytes, check: Callable[[P], int] | None,
                got: list[P]) -> int:
        """Decode ``data``, keep in ``got`` the packets that answer the request (``check``),
        and return how many of the expected replies they settle."""
        self.bytes_in += len(data)
        settled = 0
        for pkt in decoder.feed(data):
            n = 1 if check is None else check(pkt)
            if n > 0:
                got.append(pkt)
                settled += n
        return settled


class SerialTransport(Transport):
    """A serial port through pyserial (a real adapter or the emulator's pty)."""

    def __init__(self, port: str, baud: int = 1_000_000, timeout_s: float = 0.004,
                 exclusive: bool = True) -> None:
        super().__init__(port, timeout_s)
        try:
            self._ser = serial.Serial(port=port, baudrate=baud, timeout=0, write_timeout=1.0)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise BusError(f"cannot open serial port {port}: {exc}. Check the device path, "
                           "that the adapter is plugged in and that you are in the 'dialout' "
                           "group") from None
        if exclusive:
            try:
                port_lock.take(int(self._ser.fd), port, port)
            except BadInputError:
                self._ser.close()
                raise
        try:
            self._ser.set_low_latency_mode(True)
            self.low_latency = True
        except (AttributeError, NotImplementedError, ValueError, OSError, serial.SerialException):
            pass  # a pty or an adapter without ASYNC_LOW_LATENCY: best effort only

    def _open(self) -> serial.Serial:
        if not self._ser.is_open:  # pyserial would fail with a TypeError on its missing fd
            raise OSError(errno.EBADF, "the serial port is closed")
        return self._ser

    def fileno(self) -> int:
        return int(self._open().fileno())

    def _waiting(self) -> int:
        return int(self._open().in_waiting)

    def _read(self, n: int) -> bytes:
        return bytes(self._ser.read(n))

    def _write(self, data: bytes) -> None:
        self._ser.write(data)

    def _discard_input(self) -> None:
        self._ser.reset_input_buffer()

    def _close(self) -> None:
        self._ser.close()


class SocketTransport(Transport):
    """A Unix-domain stream socket (port ``unix:PATH``): the emulated bus's default link.

    The bytes go from one process to the other in the sender's system call. A pty hands
    them to a kernel worker thread first, which a loaded 2-core machine can leave waiting
    past the 4 ms reply timeout."""

    def __init__(self, port: str, timeout_s: float = 0.004, exclusive: bool = True) -> None:
        super().__init__(port, timeout_s)
        path = port[len(UNIX_PREFIX):]
        self._lock_fd = -1
        if exclusive and os.path.exists(path):  # (a missing socket is reported below)
            self._lock_fd = port_lock.open_socket_lock(path)
            try:
                port_lock.take(self._lock_fd, port, port_lock.lock_file_of_socket(path))
            except BadInputError:
                os.close(self._lock_fd)
                raise
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            sock.settimeout(1.0)
            sock.connect(path)
        except OSError as exc:
            sock.close()
            self._release_lock()
            raise BusError(f"cannot connect to the bus socket {path}: {exc.strerror or exc}. "
                           "Is the emulated bus (spm-console emulate) still running?") from None
        sock.setblocking(False)
        self._sock = sock

    def fileno(self) -> int:
        fd = self._sock.fileno()
        if fd < 0:  # closed: fail like a closed serial port (select would raise ValueError)
            raise OSError(errno.EBADF, "the bus socket is closed")
        return fd

    def _waiting(self) -> int:
        buf = fcntl.ioctl(self.fileno(), termios.FIONREAD, b"\0\0\0\0")
        return int(struct.unpack("i", buf)[0])  # the host's int

    def _read(self, n: int) -> bytes:
        try:
            data = self._sock.recv(max(n, 1))
        except BlockingIOError:
            return b""
        if not data:
            raise ConnectionResetError("the emulated bus closed the connection")
        return data

    def _write(self, data: bytes) -> None:
        view = memoryview(data)
        deadline = time.perf_counter() + 1.0  # as the serial port's write timeout
        while view:
            try:
                view = view[self._sock.send(view, socket.MSG_NOSIGNAL):]
            except BlockingIOError:
                if time.perf_counter() > deadline:
                    raise TimeoutError("write timeout") from None
                select.select([], [self._sock], [], 0.01)

    def _discard_input(self) -> None:
        while True:
            try:
                if not self._sock.recv(65536):
                    return
            except BlockingIOError:
                return

    def _release_lock(self) -> None:
        fd, self._lock_fd = self._lock_fd, -1
        if fd >= 0:
            os.close(fd)  # releases the flock

    def _close(self) -> None:
        try:
            self._sock.close()
        finally:
            self._release_lock()


def open_transport(port: str, baud: int = 1_000_000, timeout_s: float = 0.004,
                   exclusive: bool = True) -> Transport:
    """The transport for ``port``: ``unix:PATH`` a socket, anything else a serial device.
    ``exclusive``: this process alone drives the bus (:mod:`.port_lock`; refused with
    BadInputError, exit 4, naming the holder, when another one has it). Only tests of the
    emulator's own serving of several clients open a bus shared."""
    if not port:
        raise BusError("no serial port given (profile bus.port is empty): pass --port DEV "
                       "or use the emulated bus (--sim)")
    if port.startswith(UNIX_PREFIX):
        return SocketTransport(port, timeout_s, exclusive)
    return SerialTransport(port, baud, timeout_s, exclusive)
