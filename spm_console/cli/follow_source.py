"""Target sources of ``follow``: a timed CSV file and a loopback UDP socket (bounded inputs).

Orientation targets (roll, pitch, yaw relative to home, deg) become motor angles by IK in the
home working mode, here in the front end: the runtime only ever receives θ. Degrees, seconds.
"""

from __future__ import annotations

import contextlib
import json
import math
import socket
import threading
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from spm_console.errors import BadInputError, SpmError
from spm_console.profile import Profile
from spm_console.run.operator import Session
from spm_console.run.target_feed import MAX_TIMED_TARGETS, TimedTargets
from spm_console.safe_io import MB, read_text

F = NDArray[np.float64]

#: Largest targets file read.
MAX_CSV_BYTES = 10 * MB
#: Largest UDP datagram accepted (longer ones are dropped and counted).
MAX_DATAGRAM = 4096
#: Largest orientation angle accepted, deg (IK refuses what the wrist cannot reach anyway).
MAX_RPY_DEG = 90.0


def theta_of_rpy(profile: Profile, rpy_deg: F) -> F:
    """Motor angles (deg) for roll, pitch, yaw (deg) from home, home working mode."""
    from spm_console.core.ik import ik_rpy
    from spm_console.models import model_of

    r = np.asarray(rpy_deg, float).reshape(3)
    if not (np.all(np.isfinite(r)) and np.all(np.abs(r) <= MAX_RPY_DEG)):
        raise BadInputError(f"roll, pitch, yaw must be finite and within ±{MAX_RPY_DEG:g}°")
    res = ik_rpy(model_of(profile), *np.radians(r))
    th = np.asarray(res.theta_deg, float)
    if not np.all(np.isfinite(th)):
        raise BadInputError(f"no IK solution for roll, pitch, yaw = {r.tolist()}°")
    return th


def read_target_csv(profile: Profile, path: Path, rpy: bool) -> TimedTargets:
    """Rows ``t, a, b, c`` (a header line and ``#`` comments skipped); θ in degrees, or roll,
    pitch, yaw in degrees when ``rpy``."""
    text = read_text(path, "targets file", MAX_CSV_BYTES, BadInputError)
    rows: list[list[float]] = []
    header_allowed = True
    for n, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        cells = [c.strip() for c in line.split(",")]
        try:
            vals = [float(c) for c in cells]
        except ValueError:
            if header_allowed and not rows:  # one header line before the first row
                header_allowed = False
                continue
            raise BadInputError(f"{path}:{n}: four numbers expected (t and three angles)") from None
        if len(vals) != 4 or not all(math.isfinite(v) for v in vals):
            raise BadInputError(f"{path}:{n}: four finite numbers expected, got {len(vals)}")
        rows.append(vals)
        if len(rows) > MAX_TIMED_TARGETS:
            raise BadInputError(f"{path}: more than {MAX_TIMED_TARGETS} targets")
    if not rows:
        raise BadInputError(f"{path}: no targets")
    a = np.asarray(rows, float)
    th = a[:, 1:]
    if rpy:
        th = np.vstack([theta_of_rpy(profile, r) for r in th])
    return TimedTargets(a[:, 0], th)


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
            msg = json.loads(data.decode("utf-8"))
        except (UnicodeDecodeError, ValueError):
            raise BadInputError("not a JSON object") from None
        if not isinstance(msg, dict):
            raise BadInputError("not a JSON object")
        if msg.get("end") is True:
            return None
        for key in ("theta_deg", "rpy_deg"):
            if key in msg:
                v = msg[key]
                if (not isinstance(v, list) or len(v) != 3
                        or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v)):
                    raise BadInputError(f"{key} must be three numbers")
                arr = np.asarray(v, float)
                if not np.all(np.isfinite(arr)):
                    raise BadInputError(f"{key} must be finite")
                return theta_of_rpy(self.profile, arr) if key == "rpy_deg" else arr
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
                self.received += 1
                with contextlib.suppress(SpmError):
                    if theta is None:
                        session.end_follow()
                        return
                    session.set_target(theta)
