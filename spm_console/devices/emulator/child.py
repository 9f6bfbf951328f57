"""The emulated servo bus in a child process, for the console.

Real servos answer whatever the console's threads are doing; an emulator sharing
the console's interpreter (and its GIL) with the UI may miss the bus's 4 ms reply
timeout. So the console runs :func:`~spm_console.devices.emulator.bus.start_emulator`
here, in its own process: ``python -m spm_console.devices.emulator.child --parent PID``
reads the profile (JSON) and options on stdin, prints ``{"port": ...}`` and serves
until its owner stops it (SIGUSR1) or is gone. On SIGUSR2 it tells the physical wrist's leg
contacts at once and then ``{"flushed": T}``: every contact up to the instant T
(``time.perf_counter()``, shared by the processes) has been told (:meth:`EmulatorChild.flush`;
signals that arrive together count as one, and T still answers each of them), with the
physical wrist's largest winding current per joint since the flush before
(:meth:`EmulatorChild.peak_current_a`).

The emulated servos stand in for hardware, which no signal switches off: the terminating
signals (SIGINT, SIGTERM, SIGHUP, SIGQUIT: a service manager stopping every process of its
unit, a stray ``kill``) are ignored, so the servo loop's stop action still reaches them; they
end with their owner, at most :data:`PARENT_POLL_S` after it.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import select
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict
from typing import TYPE_CHECKING, Any

from spm_console.config.schema import Profile
from spm_console.devices.emulator.contacts import Collision
from spm_console.devices.emulator.faults import parse_fault
from spm_console.errors import SpmError
from spm_console.system.childproc import ChildProcess, HelperFork
from spm_console.system.cpus import place_on_loop_cpu
from spm_console.system.realtime import HELPER_PRIORITY, quick_gil_handoff, request_realtime
from spm_console.system.signals import STOP_SIGNALS

if TYPE_CHECKING:
    from spm_console.system.simclock import SimClock

#: How often the child checks that its parent is alive, s.
PARENT_POLL_S = 0.5
#: Leg contacts kept for the owner (the newest).
MAX_COLLISIONS = 10_000
#: How often the child tells its owner of the physical wrist's new leg contacts (and checks
#: its parent), s.
EVENTS_EVERY_S = 0.1
#: Longest wait of :meth:`EmulatorChild.flush` for the child's answer, s.
FLUSH_TIMEOUT_S = 1.0


class EmulatorChild(ChildProcess):
    """Handle of the child: ``port`` to open, ``stop()`` when done."""

    stop_signal = signal.SIGUSR1

    def __init__(self, profile: Profile, faults: Sequence[Any] = (),
                 initial_deg: Sequence[float] | None = None,
                 sim: SimClock | None = None, fork: HelperFork | None = None) -> None:
        super().__init__("spm_console.devices.emulator.child", what="emulated servo bus",
                         fork=fork)
        self.request = {
            "profile": profile.model_dump(mode="json"),
            "faults": [str(f) for f in faults],
            "initial_deg": None if initial_deg is None else [float(x) for x in initial_deg],
            "sim_clock": None if sim is None else sim.path,
        }
        self.clock: Callable[[], float] = time.perf_counter if sim is None else sim.now
        """The clock the child serves on (contacts and flushes are told in its time)."""
        self.port = ""
        self.realtime = ""
        self.realtime_granted = False
        self.physical = profile.plant.model == "physical"
        """The physical wrist (its leg contacts are told): see :meth:`collisions`."""
        self._collisions: list[Collision] = []
        self._lock = threading.Lock()
        self._flushed = threading.Condition(self._lock)
        self._flushed_t = float("-inf")
        """The latest instant up to which the child has told every contact."""
        self._peak_a: list[float] | None = None

    def collisions(self, since: float, until: float) -> list[Collision]:
        """The physical wrist's leg contacts that began between the monotonic instants
        ``since`` and ``until`` (:attr:`clock`: ``time.perf_counter()``, shared by the processes,
        or the simulated clock)."""
        with self._lock:
            return [c for c in self._collisions if since <= c.t <= until]

    def peak_current_a(self) -> list[float] | None:
        """The physical wrist's largest |winding current| per joint (A) between the last two
        answered :meth:`flush` calls (None: no such window, or ideal servos)."""
        with self._lock:
            return None if self._peak_a is None else list(self._peak_a)

    def flush(self, timeout_s: float = FLUSH_TIMEOUT_S) -> bool:
        """Have the child tell every leg contact up to now; True once it has (False when it
        did not answer within ``timeout_s``: it is gone or stalled)."""
        proc = self._proc
        if proc is None or proc.poll() is not None:
            return False
        asked = self.clock()
        try:
            proc.send_signal(signal.SIGUSR2)
        except OSError:
            return False
        with self._flushed:
            return self._flushed.wait_for(lambda: self._flushed_t >= asked, timeout_s)

    def _read_events(self, stdout: Any) -> None:
        try:
            for line in stdout:
                try:
                    data = json.loads(line)
                except ValueError:
                    continue
                if not isinstance(data, dict):
                    continue
                with self._flushed:
                    told = data.get("collision")
                    if isinstance(told, dict):
                        with contextlib.suppress(ValueError):  # not one: nothing to tell
                            self._collisions.append(Collision.from_json(told))
                        del self._collisions[:-MAX_COLLISIONS]
                    if isinstance(data.get("flushed"), (int, float)):
                        self._flushed_t = max(self._flushed_t, float(data["flushed"]))
                        peak = data.get("peak_current_a")
                        self._peak_a = ([float(a) for a in peak] if isinstance(peak, list)
                                        and len(peak) == 3 else None)
                        self._flushed.notify_all()
        except (OSError, ValueError):  # the pipe closed under us: the child was stopped
            return

    def launch(self) -> str:
        info = self.start(json.dumps(self.request).encode())
        out = self._proc.stdout if self._proc is not None else None
        if out is not None:  # what the child says after it is ready: the wrist's contacts
            threading.Thread(target=self._read_events, args=(out,), daemon=True,
                             name="emulator-events").start()
        self.port = str(info["port"])
        self.realtime = str(info.get("realtime", ""))
        """The scheduling the emulated servos' thread got (e.g. "SCHED_FIFO priority 45")."""
        self.realtime_granted = bool(info.get("realtime_granted", False))
        return self.port


def _parent_watch(parent: int) -> Callable[[], bool]:
    """Whether the front end ``parent`` (a pid, 0: none) is gone. Started by it, this process
    is re-parented when it dies; forked by its warm start, the warm start is the parent, and
    a pidfd of the front end says when it has ended."""
    if not parent:
        return lambda: False
    if os.getppid() == parent:
        return lambda: os.getppid() != parent
    try:
        fd = os.pidfd_open(parent)
    except OSError:  # gone already (or no pidfd: then no warm start forked this process)
        return lambda: True
    return lambda: bool(select.select([fd], [], [], 0)[0])


def main(argv: Sequence[str] | None = None) -> int:
    from spm_console.config.load import parse_profile
    from spm_console.devices.emulator.bus import start_emulator
    from spm_console.system.simclock import attached

    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--parent", type=int, default=0, help="exit when this process is gone")
    args = parser.parse_args(argv)
    for sig in STOP_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)

    place_on_loop_cpu()  # the emulated servos answer the loop: the same CPU, see spm_console.system.cpus
    request_realtime(HELPER_PRIORITY)  # shares the emulator's GIL: see realtime.HELPER_PRIORITY
    quick_gil_handoff()  # the servo thread answers within ~0.5 ms of a request
    # the handlers only set a flag and write a byte to a pipe the loop waits on: no lock is
    # taken in a handler (the main thread may hold it when the signal lands)
    wake_r, wake_w = os.pipe()
    os.set_blocking(wake_w, False)
    asked = {"stop": 0, "flush": 0}  # counters: the loop never writes them

    def on_signal(sig: int, *_: Any) -> None:
        asked["stop" if sig == signal.SIGUSR1 else "flush"] += 1
        with contextlib.suppress(OSError):
            os.write(wake_w, b"!")

    signal.signal(signal.SIGUSR1, on_signal)
    signal.signal(signal.SIGUSR2, on_signal)
    parent_gone = _parent_watch(args.parent)
    try:
        req = json.loads(sys.stdin.read())
        profile = parse_profile(req["profile"], "profile")
        faults = [parse_fault(f) for f in req.get("faults", [])]
        path = req.get("sim_clock")
        sim = None if path is None else attached(str(path))
        em = start_emulator(profile, faults, record=False, initial_deg=req.get("initial_deg"),
                            sim=sim)
    except (SpmError, ValueError, KeyError) as exc:
        msg = getattr(exc, "message", str(exc))
        sys.stdout.write(json.dumps({"error": msg}) + "\n")
        return 1
    for _ in range(100):  # the serving thread asks for real-time scheduling as it starts
        if em.realtime.detail != "not serving yet":
            break
        time.sleep(0.01)
    sys.stdout.write(json.dumps({"port": em.port, "realtime": em.realtime.detail,
                                 "realtime_granted": em.realtime.policy == "SCHED_FIFO"}) + "\n")
    sys.stdout.flush()
    told = 0
    try:
        while not asked["stop"] and em.running:
            with contextlib.suppress(InterruptedError):
                if select.select([wake_r], [], [], EVENTS_EVERY_S)[0]:
                    os.read(wake_r, 4096)
            if asked["stop"] or parent_gone():
                break
            flushes = asked["flush"]  # one read: a later request finds its byte in the pipe
            now = time.perf_counter() if em.sim is None else em.sim.now()
            peak = None
            if em.wrist is not None:  # the legs' contacts, told to the owner as they begin
                if flushes > told:  # steps the wrist up to now first (the serving thread waits)
                    peak = em.take_peak_current()
                for c in em.wrist.contacts.take():
                    sys.stdout.write(json.dumps({"collision": asdict(c)}) + "\n")
            if flushes > told:
                sys.stdout.write(json.dumps({
                    "flushed": now,
                    "peak_current_a": None if peak is None else [float(a) for a in peak]}) + "\n")
                told = flushes
            sys.stdout.flush()
    finally:
        em.stop()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
