"""The emulated servo bus in a child process, for the console.

Real servos answer whatever the console's threads are doing; an emulator sharing
the console's interpreter (and its GIL) with the UI may miss the bus's 4 ms reply
timeout. So the console runs :func:`~spm_console.devices.emulator.bus.start_emulator`
here, in its own process: ``python -m spm_console.devices.emulator.child --parent PID``
reads the profile (JSON) and options on stdin, prints ``{"port": ...}`` and serves
until its owner stops it (SIGUSR1) or is gone.

The emulated servos stand in for hardware, which no signal switches off: the terminating
signals (SIGINT, SIGTERM, SIGHUP, SIGQUIT: a service manager stopping every process of its
unit, a stray ``kill``) are ignored, so the servo loop's stop action still reaches them; they
end with their owner, at most :data:`PARENT_POLL_S` after it.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
from collections.abc import Sequence
from typing import Any

from spm_console.config.schema import Profile
from spm_console.devices.emulator.faults import parse_fault
from spm_console.errors import SpmError
from spm_console.system.childproc import ChildProcess
from spm_console.system.cpus import place_on_loop_cpu
from spm_console.system.realtime import HELPER_PRIORITY, quick_gil_handoff, request_realtime
from spm_console.system.signals import STOP_SIGNALS

#: How often the child checks that its parent is alive, s.
PARENT_POLL_S = 0.5


class EmulatorChild(ChildProcess):
    """Handle of the child: ``port`` to open, ``stop()`` when done."""

    stop_signal = signal.SIGUSR1

    def __init__(self, profile: Profile, faults: Sequence[Any] = (),
                 initial_deg: Sequence[float] | None = None) -> None:
        super().__init__("spm_console.devices.emulator.child", what="emulated servo bus")
        self.request = {
            "profile": profile.model_dump(mode="json"),
            "faults": [str(f) for f in faults],
            "initial_deg": None if initial_deg is None else [float(x) for x in initial_deg],
        }
        self.port = ""
        self.realtime = ""
        self.realtime_granted = False

    def launch(self) -> str:
        info = self.start(json.dumps(self.request).encode())
        self.port = str(info["port"])
        self.realtime = str(info.get("realtime", ""))
        """The scheduling the emulated servos' thread got (e.g. "SCHED_FIFO priority 45")."""
        self.realtime_granted = bool(info.get("realtime_granted", False))
        return self.port


def main(argv: Sequence[str] | None = None) -> int:
    from spm_console.config.load import parse_profile
    from spm_console.devices.emulator.bus import start_emulator

    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--parent", type=int, default=0, help="exit when this process is gone")
    args = parser.parse_args(argv)
    for sig in STOP_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)

    place_on_loop_cpu()  # the emulated servos answer the loop: the same CPU, see spm_console.system.cpus
    request_realtime(HELPER_PRIORITY)  # shares the emulator's GIL: see realtime.HELPER_PRIORITY
    quick_gil_handoff()  # the servo thread answers within ~0.5 ms of a request
    stop = threading.Event()
    signal.signal(signal.SIGUSR1, lambda *_: stop.set())
    try:
        req = json.loads(sys.stdin.read())
        profile = parse_profile(req["profile"], "profile")
        faults = [parse_fault(f) for f in req.get("faults", [])]
        em = start_emulator(profile, faults, record=False, initial_deg=req.get("initial_deg"))
    except (SpmError, ValueError, KeyError) as exc:
        msg = getattr(exc, "message", str(exc))
        sys.stdout.write(json.dumps({"error": msg}) + "\n")
        return 1
    for _ in range(100):  # the serving thread asks for real-time scheduling as it starts
        if em.realtime.detail != "not serving yet":
            break
        stop.wait(0.01)
    sys.stdout.write(json.dumps({"port": em.port, "realtime": em.realtime.detail,
                                 "realtime_granted": em.realtime.policy == "SCHED_FIFO"}) + "\n")
    sys.stdout.flush()
    try:
        while not stop.wait(PARENT_POLL_S) and em.running:
            if args.parent and os.getppid() != args.parent:
                break
    finally:
        em.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
