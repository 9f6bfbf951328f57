"""Is a Dask scheduler at ``--scheduler tcp://HOST:PORT``? Asked by hand before Dask's client
connects, so that another service at the address is refused within seconds.

On a connection a Dask scheduler speaks first: its handshake, one message in Dask's TCP
framing (8 bytes giving the length of the frames block, then the block, which holds a msgpack
map with the keys ``compression``, ``python`` and ``pickle-protocol``). Dask's own client
trusts the length it reads: a service that sends other bytes makes it allocate what they
claim (exabytes), or fail an assertion, and one that says nothing keeps it waiting with no
deadline. Here the length is bounded and every read has one.
"""

from __future__ import annotations

import socket
import struct
import time

from spm_console.errors import BadInputError

#: How long the address may take to accept a connection and send its handshake, s.
PROBE_TIMEOUT_S = 5.0
#: Largest handshake taken from a scheduler, bytes (Dask's is under a hundred).
MAX_HANDSHAKE_BYTES = 64 * 1024
#: A key of every Dask handshake (distributed 2022 and later).
HANDSHAKE_KEY = b"pickle-protocol"
_LENGTH = struct.Struct("Q")  # Dask's framing: native byte order, as both its ends write it


class _NotDaskError(Exception):
    """What the service at the address did instead of a Dask handshake."""


def _host_port(address: str) -> tuple[str, int]:
    """(host, port) of ``tcp://HOST:PORT`` or ``HOST:PORT`` (an IPv6 host in brackets)."""
    rest = address.removeprefix("tcp://")
    host, _, port = rest.rpartition(":")
    return host.removeprefix("[").removesuffix("]"), int(port)


def _read(sock: socket.socket, n: int, deadline: float) -> bytes:
    data = bytearray()
    while len(data) < n:
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError
        sock.settimeout(left)
        chunk = sock.recv(min(n - len(data), 65536))
        if not chunk:
            raise _NotDaskError("it closed the connection without a Dask handshake")
        data += chunk
    return bytes(data)


def _handshake(sock: socket.socket, deadline: float) -> None:
    """Read the scheduler's handshake and answer it with the same (a peer's handshake of the
    same settings), so that the scheduler sees a client that came and went, not an error."""
    head = _read(sock, _LENGTH.size, deadline)
    (length,) = _LENGTH.unpack(head)
    if not 0 < length <= MAX_HANDSHAKE_BYTES:
        raise _NotDaskError(f"its first message claims {length:,} bytes, not a Dask handshake")
    block = _read(sock, length, deadline)
    if HANDSHAKE_KEY not in block:
        raise _NotDaskError("its first message is not a Dask handshake")
    sock.settimeout(max(deadline - time.monotonic(), 0.001))
    sock.sendall(head + block)


def probe_scheduler(address: str, timeout: float | None = None) -> None:
    """Refuse (BadInputError), within ``timeout`` seconds (default :data:`PROBE_TIMEOUT_S`),
    an address where no Dask scheduler answers: nothing listening, a service that says
    nothing, or one whose first message is not a Dask handshake of at most
    :data:`MAX_HANDSHAKE_BYTES`. ``tls://`` addresses are left to Dask (their bytes are
    encrypted)."""
    if address.startswith("tls://"):
        return
    timeout = PROBE_TIMEOUT_S if timeout is None else timeout
    host, port = _host_port(address)
    deadline = time.monotonic() + timeout
    try:
        with socket.create_connection((host, port), timeout=timeout) as sock:
            _handshake(sock, deadline)
    except TimeoutError:
        raise BadInputError(f"--scheduler {address}: no Dask scheduler answered within "
                            f"{timeout:g} s") from None
    except _NotDaskError as exc:
        raise BadInputError(f"--scheduler {address}: the service there is not a Dask scheduler "
                            f"({exc})") from None
    except OSError as exc:
        raise BadInputError(f"--scheduler {address}: no Dask scheduler answered "
                            f"({exc.strerror or exc})") from None
