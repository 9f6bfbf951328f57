"""The live target source of ``follow --udp``: a loopback UDP socket (bounded messages).

Orientation targets (roll, pitch, yaw relative to home, deg) become motor angles by IK in the
home working mode, here in the front end: the runtime only ever receives θ. Degrees.
"""

from __future__ import annotations

import contextlib
import socket
import threading
from typing import Any

import numpy as np
from numpy.typing import NDArray

from spm_console.config.schema import Profile
from spm_console.errors import BadInputError, SpmError
from spm_console.numbers import NotANumberError, json_loads, json_number
from spm_console.services.session import Session
from spm_console.store.target_file import theta_of_rpy

F = NDArray[np.float64]

#: Largest UDP datagram accepted (longer ones are dropped and counted).
MAX_DATAGRAM = 4096


class UdpTargets:
    """A socket on 127.0.0.1:``port`` forwarding each valid JSON message to the following:
    ``{"theta_deg": [a, b, c]}``, ``{"rpy_deg": [r, p, y]}``, ``{"end": true}``. Anything
    else (too long, not JSON, out of range) is dropped and counted."""

    def __init__(self, profile: Profile, port: int) -> None:
        self.profile = profile
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.bind(("127.0.0.1", port))
        except OSError as exc:
            self.sock.close()
            raise BadInputError(f"--udp {port}: cannot listen on 127.0.0.1:{port} ({exc.strerror})") from None
        self.sock.settimeout(0.05)
        self.stop = threading.Event()
        self.received = 0
        self.dropped = 0
        self.last_error = ""

    def __enter__(self) -> UdpTargets:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.sock.close()

    def counts(self) -> dict[str, Any]:
        return {"received": self.received, "dropped": self.dropped, "last_error": self.last_error}

    def parse(self, data: bytes) -> F | None:
        """θ (deg) of one message, None for ``end``; BadInputError when malformed."""
        if len(data) > MAX_DATAGRAM:
            raise BadInputError(f"message longer than {MAX_DATAGRAM} bytes")
        try:
            msg = json_loads(data.decode("utf-8"))
        except NotANumberError as exc:
            raise BadInputError(f"not a valid message: {exc}") from None
        except (UnicodeDecodeError, ValueError, RecursionError):
            raise BadInputError("not a JSON object") from None
        if not isinstance(msg, dict):
            raise BadInputError("not a JSON object")
        if msg.get("end") is True:
            return None
        for key in ("theta_deg", "rpy_deg"):
            if key in msg:
                v = msg[key]
                if not isinstance(v, list) or len(v) != 3:
                    raise BadInputError(f"{key} must be three numbers")
                try:
                    arr = np.array([json_number(x) for x in v])
                except NotANumberError as exc:
                    raise BadInputError(f"{key} must be three finite numbers ({exc})") from None
                return theta_of_rpy(self.profile, arr, key) if key == "rpy_deg" else arr
        raise BadInputError('expected {"theta_deg": [..]}, {"rpy_deg": [..]} or {"end": true}')

    def pump(self, session: Session) -> None:
        """Forward messages to ``session`` until ``end`` or the following stops."""
        while not self.stop.is_set() and session.moving.is_set():
            try:
                data = self.sock.recv(MAX_DATAGRAM + 1)
            except TimeoutError:
                continue
            except OSError:
                return
            for line in data.splitlines() or [data]:
                if not line.strip():
                    continue
                try:
                    theta = self.parse(line)
                except SpmError as exc:
                    self.dropped += 1
                    self.last_error = exc.message
                    continue
                except Exception as exc:  # a bug: this message is dropped, the source lives on
                    self.dropped += 1
                    self.last_error = f"internal error on a message: {exc!r}"
                    continue
                self.received += 1
                with contextlib.suppress(SpmError):
                    if theta is None:
                        session.following.end_follow()
                        return
                    session.following.set_target(theta)
