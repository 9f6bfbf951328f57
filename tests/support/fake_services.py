"""TCP services on the loopback that are not what a client expects, each served by a thread of
the test's own process: a garbage length prefix, random bytes, an echo, silence, a hang-up,
or a Dask scheduler's handshake and nothing after it."""

from __future__ import annotations

import contextlib
import random
import socket
import struct
import threading
from collections.abc import Iterator

#: What a Dask scheduler sends first (distributed's framing of its handshake map).
DASK_HANDSHAKE = (struct.pack("Q", 58) + struct.pack("Q", 1) + struct.pack("Q", 42)
                  + b"\x83\xabcompression\xc0\xa6python\x93\x03\x0b\x07"
                  b"\xafpickle-protocol\x05")
#: A first message claiming more bytes than any machine holds (an 8-byte length of all ones).
HUGE_LENGTH = b"\xff" * 64
#: Random bytes, the same on every run.
RANDOM = random.Random(0).randbytes(4096)

FIRST_BYTES = {"huge": HUGE_LENGTH, "random": RANDOM, "dask": DASK_HANDSHAKE}
BEHAVIOURS = ("huge", "random", "dask", "echo", "silent", "hangup")


def _serve(conn: socket.socket, behaviour: str, stop: threading.Event) -> None:
    with conn, contextlib.suppress(OSError):
        if behaviour == "hangup":
            return
        conn.sendall(FIRST_BYTES.get(behaviour, b""))
        conn.settimeout(0.1)
        while not stop.is_set():
            try:
                data = conn.recv(65536)
            except TimeoutError:
                continue
            if not data:
                return
            if behaviour == "echo":
                conn.sendall(data)


@contextlib.contextmanager
def tcp_service(behaviour: str) -> Iterator[int]:
    """A service on 127.0.0.1 acting as ``behaviour`` (one of :data:`BEHAVIOURS`) for every
    connection, until the block ends; yields its port."""
    assert behaviour in BEHAVIOURS, behaviour
    stop = threading.Event()
    server = socket.create_server(("127.0.0.1", 0))
    server.settimeout(0.1)
    threads: list[threading.Thread] = []

    def accept() -> None:
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            t = threading.Thread(target=_serve, args=(conn, behaviour, stop), daemon=True)
            t.start()
            threads.append(t)

    acceptor = threading.Thread(target=accept, daemon=True)
    acceptor.start()
    try:
        yield server.getsockname()[1]
    finally:
        stop.set()
        acceptor.join()
        server.close()
        for t in threads:
            t.join()
