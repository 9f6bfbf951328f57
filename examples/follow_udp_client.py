"""Steer the wrist live over UDP: a 0.5 Hz ±10° roll around home for a few seconds at 50 Hz.

Start the follower first (emulated bus here), then this client:

    .venv/bin/spm-console follow --sim --udp 9870
    .venv/bin/python examples/follow_udp_client.py --port 9870 --seconds 6

Messages are JSON lines on 127.0.0.1: {"rpy_deg": [roll, pitch, yaw]} (degrees, relative to
home) or {"theta_deg": [t1, t2, t3]} (motor angles); {"end": true} ends the following (the
wrist settles on the last target). If no message arrives for the follower's --deadman time
(default 0.5 s), it holds the wrist where it is until messages resume.
"""

from __future__ import annotations

import argparse
import json
import math
import socket
import time


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--port", type=int, default=9870)
    p.add_argument("--seconds", type=float, default=6.0)
    p.add_argument("--amplitude", type=float, default=10.0, help="roll amplitude, deg")
    p.add_argument("--hz", type=float, default=0.5, help="frequency of the roll, Hz")
    args = p.parse_args()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    addr = ("127.0.0.1", args.port)
    t0 = time.monotonic()
    while (t := time.monotonic() - t0) < args.seconds:
        roll = args.amplitude * math.sin(2 * math.pi * args.hz * t)
        sock.sendto(json.dumps({"rpy_deg": [roll, 0.0, 0.0]}).encode(), addr)
        time.sleep(0.02)
    sock.sendto(json.dumps({"rpy_deg": [0.0, 0.0, 0.0]}).encode(), addr)
    time.sleep(0.05)
    sock.sendto(b'{"end": true}', addr)


if __name__ == "__main__":
    main()
