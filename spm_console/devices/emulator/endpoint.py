"""Where the emulated bus is reached: a Unix-domain socket (default) or a pseudo-terminal.

``socket``: the emulator listens on ``unix:PATH`` (a fresh folder only this user can
enter) and serves every client that connects, each on its own stream with its own packet
decoder; a reply goes back on the stream its request came in on. The bytes cross from one
process to the other in the sender's system call.

``pty``: a pseudo-terminal pair, raw; clients open the slave as a serial device, so any
serial tool (pyserial, the vendor SDK, Dynamixel Wizard) can talk to it. The kernel moves
the bytes between the two sides in a worker thread of its own, which a loaded 2-core
machine can leave waiting past the bus's 4 ms reply timeout: that is why the socket is the
default for the emulated bus behind ``--sim`` and the console.
"""

from __future__ import annotations

import contextlib
import os
import select
import shutil
import socket
import tempfile
import time
import tty
from collections.abc import Callable, Sequence
from typing import Literal, Protocol

from spm_console.devices.dynamixel.transport import UNIX_PREFIX
from spm_console.errors import BusError

Link = Literal["socket", "pty"]
#: Clients served at once on the socket (a further one is turned away: its first request fails).
MAX_CLIENTS = 32
#: How long a reply may wait for a full client's stream before it is dropped, s.
WRITE_WAIT_S = 0.5


class Decoder(Protocol):
    """What the bus needs of Decoder1 / Decoder2."""

    skipped: int

    @property
    def pending(self) -> int: ...

    def feed(self, data: bytes) -> Sequence[object]: ...

    def reset(self) -> None: ...


class Channel:
    """One client's byte stream, with its own packet decoder."""

    def __init__(self, fd: int, decoder: Decoder, sock: socket.socket | None = None) -> None:
        self.fd = fd
        self.decoder = decoder
        self.last_rx = 0.0
        """When bytes last came in (``time.perf_counter()``)."""
        self.sock = sock
        self.closed = False

    def read(self) -> bytes:
        """What is there to read; b"" when nothing is (``closed`` set when the client left)."""
        try:
            data = self.sock.recv(4096) if self.sock is not None else os.read(self.fd, 4096)
        except BlockingIOError:
            return b""
        except OSError:
            self.closed = True
            return b""
        if not data and self.sock is not None:
            self.closed = True
        return data

    def write(self, raw: bytes) -> None:
        """Send a reply; given up after :data:`WRITE_WAIT_S` on a stream nobody reads."""
        if self.closed:
            return
        view = memoryview(raw)
        deadline = time.perf_counter() + WRITE_WAIT_S
        while view:
            try:
                n = (self.sock.send(view, socket.MSG_NOSIGNAL) if self.sock is not None
                     else os.write(self.fd, view))
                view = view[n:]
            except BlockingIOError:
                if time.perf_counter() > deadline:
                    return
                select.select([], [self.fd], [], 0.01)
            except OSError:
                self.closed = self.sock is not None
                return


class Endpoint:
    """The emulated bus's end of the link: ``port`` for clients, ``fds()`` to wait on,
    ``receive(ready)`` for what came in."""

    port: str

    def fds(self) -> list[int]:
        raise NotImplementedError

    def receive(self, ready: list[int]) -> list[tuple[Channel, bytes]]:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError


class PtyEndpoint(Endpoint):
    """A raw pseudo-terminal pair; ``port`` is the slave's path."""

    def __init__(self, decoder: Callable[[], Decoder]) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.port = os.ttyname(self._slave)
        self._channel = Channel(self._master, decoder())

    def fds(self) -> list[int]:
        return [self._master]

    def receive(self, ready: list[int]) -> list[tuple[Channel, bytes]]:
        if self._master not in ready:
            return []
        data = self._channel.read()
        return [(self._channel, data)] if data else []

    def close(self) -> None:
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)


class SocketEndpoint(Endpoint):
    """A listening Unix-domain socket in a private folder; ``port`` is ``unix:PATH``."""

    def __init__(self, decoder: Callable[[], Decoder]) -> None:
        self._decoder = decoder
        # mode 0700: this user's clients only; in a short folder (a socket's path has at most
        # 107 bytes)
        self._dir = tempfile.mkdtemp(prefix="spm-bus-", dir=_short_tmp())
        path = os.path.join(self._dir, "bus")
        self._listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            self._listener.bind(path)
            self._listener.listen(MAX_CLIENTS)
            self._listener.setblocking(False)
        except OSError as exc:
            self._listener.close()
            shutil.rmtree(self._dir, ignore_errors=True)
            raise BusError(f"cannot serve the emulated bus on {path}: {exc.strerror or exc}; "
                           "set [emulator] link = \"pty\" in the profile") from None
        self.port = UNIX_PREFIX + path
        self._channels: dict[int, Channel] = {}

    def fds(self) -> list[int]:
        return [self._listener.fileno(), *self._channels]

    def receive(self, ready: list[int]) -> list[tuple[Channel, bytes]]:
        if self._listener.fileno() in ready:
            self._accept()
        got: list[tuple[Channel, bytes]] = []
        for fd in ready:
            ch = self._channels.get(fd)
            if ch is None:
                continue
            data = ch.read()
            if data:
                got.append((ch, data))
            if ch.closed:
                self._drop(ch)
        return got

    def _accept(self) -> None:
        try:
            conn, _ = self._listener.accept()
        except OSError:
            return
        if len(self._channels) >= MAX_CLIENTS:
            conn.close()
            return
        conn.setblocking(False)
        self._channels[conn.fileno()] = Channel(conn.fileno(), self._decoder(), conn)

    def _drop(self, ch: Channel) -> None:
        self._channels.pop(ch.fd, None)
        if ch.sock is not None:
            ch.sock.close()

    def close(self) -> None:
        for ch in list(self._channels.values()):
            self._drop(ch)
        with contextlib.suppress(OSError):
            self._listener.close()
        shutil.rmtree(self._dir, ignore_errors=True)


def _short_tmp() -> str:
    """A writable folder for the socket whose path leaves room under the 107-byte limit."""
    for base in (os.environ.get("XDG_RUNTIME_DIR"), tempfile.gettempdir(), "/tmp"):
        if base and len(base) < 64 and os.path.isdir(base) and os.access(base, os.W_OK):
            return base
    return tempfile.gettempdir()


def open_endpoint(link: Link, decoder: Callable[[], Decoder]) -> Endpoint:
    """The emulated bus's end of a ``link``, each client's packets read by a ``decoder()``."""
    return SocketEndpoint(decoder) if link == "socket" else PtyEndpoint(decoder)
