"""Simulated time shared by the processes of one emulated session: the servo loop, its bus and
the emulated wrist step in lockstep instead of waiting on the wall clock.

One small file mapped into every process that takes part (:class:`SimClock`; the session
creates it, the motion process and the emulator attach to it by path) holds:

* ``now``: the simulated time, s. It only moves forward, and only when someone waits: the
  servo loop's wait for its next period, the transport's wait for a reply (the bytes' time on
  the wire, or a timeout), a stop action's repeated hold. Nothing else advances it.
* ``tx`` and ``rx``: the bytes the bus's client has written and the bytes the emulated bus has
  read and answered. :meth:`SimClock.advance_to` first waits (on the wall clock, bounded)
  until the emulator has answered everything sent: every instruction is applied at the
  simulated instant it was sent, whatever the machine's load, so runs are deterministic.
* ``due``: the simulated time of the emulator's earliest reply held back by a ``delay``
  fault (+inf: none), so a client waiting for it moves the clock there instead of waiting;
  the emulator writes it after each reply it sends, so ``due > now`` once every reply due by
  now is on its way.
* ``stops sent`` and ``stops taken``: the E-stop messages the front end has sent and those
  the motion process has handed to its loop. Time moves on only once every E-stop sent is
  taken (bounded, as the bus's bytes): an E-stop acts at the simulated instant it was sent,
  however long the message waited for a core.

The emulator integrates its physics up to the clock's value when it handles a request
(never on its own schedule): the twin steps exactly to the instant each request asks about.

Limits, stated plainly: one bus client at a time counts its bytes (the motion process owns the
port exclusively); values are aligned 8-byte words, written by one process each (``now`` by the
client's side, ``rx`` and ``due`` by the emulator, ``stops sent`` by the front end, ``stops
taken`` by the motion process). Seconds throughout.
"""

from __future__ import annotations

import contextlib
import math
import mmap
import os
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

#: Longest wall-clock wait for the emulator to answer what was sent before time moves on, s
#: (it answers within a millisecond; longer, it is gone or stopped: time moves on anyway and
#: the bus's own timeouts report it).
CATCH_UP_S = 2.0
#: Wall-clock poll of that wait, s, after its first SPIN_S, when it only yields the core
#: (a sleep of 0.1 ms takes about 0.16 ms, and a servo period waits on the emulator a few times).
#: With a single core to run on, the waiter never spins: a real-time waiter would keep the
#: emulator it waits for off that core.
POLL_S = 0.0001
SPIN_S = 0.002 if len(os.sched_getaffinity(0)) > 1 else 0.0
#: A wait that starts this long (wall clock) after the last paced one starts a new run of
#: paced waits: time spent idle between motions is not made up for, s.
PACE_GAP_S = 0.25
_SIZE = 64
_NOW, _DUE, _RATE = 0, 1, 4  # float64 words
_TX, _RX, _STOPS_SENT, _STOPS_TAKEN = 2, 3, 5, 6  # uint64 words


class SimClock:
    """A simulated clock in a shared file (see the module docstring). Create one with
    :meth:`create`, attach to it elsewhere with :meth:`attach`."""

    def __init__(self, path: str, owner: bool = False) -> None:
        self.path = path
        self._owner = owner
        fd = os.open(path, os.O_RDWR)
        try:
            self._mm = mmap.mmap(fd, _SIZE)
        finally:
            os.close(fd)
        self._f = np.ndarray((5,), np.float64, buffer=self._mm)
        self._u = np.ndarray((7,), np.uint64, buffer=self._mm)
        self._paced: tuple[float, float] | None = None
        """(simulated, wall-clock) instants of this process's last paced wait."""
        self._stops_lost = 0
        """E-stops sent that this process counts as never to be taken: not taken in time, or
        sent before the motion process that takes them began."""
        self._taker: int | None = None
        """The thread that takes the E-stop messages (it never waits for them itself)."""

    @classmethod
    def create(cls, start_s: float = 0.0, rate: float = 0.0) -> SimClock:
        """A new clock at ``start_s``, in a file of its own (removed by :meth:`close`);
        ``rate``: the simulated seconds its waits take per wall-clock second (0: no pacing, as
        fast as the processes compute; 1: real time)."""
        if not (math.isfinite(rate) and rate >= 0.0):
            raise ValueError(f"SimClock: rate must be finite and ≥ 0, not {rate}")
        shm = Path("/dev/shm")
        fd, path = tempfile.mkstemp(prefix="spm-simclock-",
                                    dir=str(shm) if shm.is_dir() else None)
        try:
            os.write(fd, bytes(_SIZE))
        finally:
            os.close(fd)
        clock = cls(path, owner=True)
        clock._f[_NOW] = float(start_s)
        clock._f[_DUE] = math.inf
        clock._f[_RATE] = float(rate)
        return clock

    @classmethod
    def attach(cls, path: str) -> SimClock:
        """The clock another process created at ``path``."""
        return cls(path)

    def close(self) -> None:
        """Unmap (and, for the creator, remove the file)."""
        if self._owner:
            with contextlib.suppress(OSError):
                os.unlink(self.path)

    # --- time -------------------------------------------------------------------------
    def now(self) -> float:
        """The simulated time, s."""
        return float(self._f[_NOW])

    def advance_to(self, t: float) -> None:
        """Move the clock to ``t`` (never back), once the emulator has answered everything
        sent and every E-stop sent is taken."""
        self.catch_up()
        if t > self._f[_NOW]:
            self._take_stops()
            self._f[_NOW] = float(t)

    @property
    def rate(self) -> float:
        """Simulated seconds per wall-clock second of :meth:`sleep` (0: not paced)."""
        return float(self._f[_RATE])

    def sleep(self, dt: float, rate: float | None = None) -> None:
        """Wait ``dt`` s of simulated time: at once on the wall clock, or paced at ``rate``
        (default :attr:`rate`; 0: not paced) simulated seconds per wall-clock second. Paced
        waits keep their own schedule (no drift), from the first after an idle gap
        (:data:`PACE_GAP_S`)."""
        target = self.now() + max(0.0, float(dt))
        rate = self.rate if rate is None else rate
        if rate > 0.0:
            wall = time.perf_counter()
            last = self._paced
            if last is None or wall - last[1] > PACE_GAP_S + (target - last[0]) / rate:
                last = (self.now(), wall)
            due = last[1] + (target - last[0]) / rate
            if due > wall:
                time.sleep(due - wall)
            self._paced = (target, max(due, wall))
        self.advance_to(target)

    # --- the bus's bytes ----------------------------------------------------------------
    def sent(self, n: int) -> None:
        """The bus client wrote ``n`` bytes."""
        self._u[_TX] += np.uint64(n)

    def answered(self, n: int) -> None:
        """The emulator read ``n`` bytes and wrote every reply due for them."""
        self._u[_RX] += np.uint64(n)

    def caught_up(self) -> bool:
        """Whether the emulator has answered every byte the client sent and written every
        held-back reply due by now."""
        return int(self._u[_RX]) >= int(self._u[_TX]) and float(self._f[_DUE]) > self.now()

    def catch_up(self, wait_s: float = CATCH_UP_S) -> bool:
        """Wait (wall clock, at most ``wait_s``) until :meth:`caught_up`; whether it was."""
        if self.caught_up():
            return True
        now = time.perf_counter()
        end, spin_end = now + wait_s, now + SPIN_S
        while (now := time.perf_counter()) < end:
            time.sleep(0.0 if now < spin_end else POLL_S)
            if self.caught_up():
                return True
        return False

    # --- E-stops ----------------------------------------------------------------------
    def stop_sent(self, n: int = 1) -> None:
        """The front end is sending ``n`` E-stop messages (−1: one it sent could not go)."""
        self._u[_STOPS_SENT] = np.uint64(max(0, int(self._u[_STOPS_SENT]) + n))

    def takes_stops(self) -> None:
        """The calling thread reads the E-stop messages: its own waits never hold time for
        them (it could not take one while it waited)."""
        self._taker = threading.get_ident()
        self._stops_lost = self._stops_unseen()

    def stop_taken(self) -> None:
        """The motion process handed an E-stop message to its loop."""
        self._u[_STOPS_TAKEN] += np.uint64(1)

    def _stops_unseen(self) -> int:
        return int(self._u[_STOPS_SENT]) - int(self._u[_STOPS_TAKEN])

    def stops_pending(self) -> int:
        """E-stops sent and not taken (nor counted lost by this process)."""
        pending = self._stops_unseen() - self._stops_lost
        if pending < 0:  # one counted lost was taken after all, or its send withdrawn
            self._stops_lost = max(0, self._stops_unseen())
            return 0
        return pending

    def _take_stops(self) -> None:
        """Wait (wall clock, at most :data:`CATCH_UP_S`) until every E-stop sent is taken; one not
        taken by then is counted lost (time moves on, and is not held for it again)."""
        if not self.stops_pending() or threading.get_ident() == self._taker:
            return
        end = time.perf_counter() + CATCH_UP_S
        while time.perf_counter() < end:
            time.sleep(POLL_S)
            if not self.stops_pending():
                return
        self._stops_lost = max(0, self._stops_unseen())

    @property
    def due(self) -> float:
        """The simulated time of the emulator's earliest held-back reply (+inf: none)."""
        return float(self._f[_DUE])

    @due.setter
    def due(self, t: float) -> None:
        self._f[_DUE] = float(t)


_ATTACHED: dict[str, SimClock] = {}


def attached(path: str) -> SimClock:
    """The clock at ``path``, attached once per process."""
    clock = _ATTACHED.get(path)
    if clock is None:
        clock = _ATTACHED[path] = SimClock.attach(path)
    return clock
