"""The front end's side of the motion process (:mod:`spm_console.motion.server`).

:class:`MotionClient` starts the motion process (:mod:`.warm_start`) with one end of a
socket pair, sends it what to serve, and then talks to it with the typed messages of
:mod:`spm_console.motion.protocol`: requests and E-stops out, replies and telemetry in,
a heartbeat every :data:`~spm_console.motion.server.HEARTBEAT_S` during a motion. When
the process dies, every waiting call raises :class:`MotionProcessLostError` (exit 27).
"""

from __future__ import annotations

import contextlib
import queue
import socket
import subprocess
import threading
import time
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar, cast

import numpy as np
from numpy.typing import NDArray

from spm_console.config.schema import Profile
from spm_console.core.plan import Plan
from spm_console.core.planning.follow.timed import TimedTargets
from spm_console.devices.base import ServoStatus
from spm_console.errors import BusError, MotionProcessLostError, SpmError, error_for
from spm_console.motion.homing import HomingResult
from spm_console.motion.nudge import NudgeResult
from spm_console.motion.plan_check import PlanCheck
from spm_console.motion.protocol import (
    ESTOP_SIGNAL,
    Close,
    EndFollow,
    EStop,
    Execute,
    Failed,
    Follow,
    Heartbeat,
    Home,
    Nudge,
    Ping,
    Planned,
    Query,
    ReadPosition,
    Reboot,
    Reply,
    Request,
    SetTarget,
    Status,
    Telemetry,
    Torque,
    Verify,
)
from spm_console.motion.runs import RunContext
from spm_console.motion.sample import Sample
from spm_console.motion.segments import ExecutionResult
from spm_console.motion.server import HEARTBEAT_S, REQUEST_TIMEOUT_S, Start
from spm_console.motion.servo_query import BusQuery, BusReport
from spm_console.motion.servo_tools import ServoHealth
from spm_console.services.forked_process import MotionProcessHandle
from spm_console.services.warm_start import start_motion_process
from spm_console.system.simclock import SimClock

if TYPE_CHECKING:  # the follower loads scipy.optimize and osqp (~1.2 s): not for a front end
    from spm_console.motion.follow.run import FollowOutcome

T = TypeVar("T")

VERIFY_TIMEOUT_S = 300.0
"""How long a plan's verification may take: on a cold cache the motion process builds this
profile's workspace first (a few seconds on a 2-core machine; a fine grid takes longer)."""


class MotionClient:
    """The front end's handle on the motion process (thread-safe; one motion at a time)."""

    def __init__(self, profile: Profile, port: str, *, cache_dir: str | Path | None = None,
                 logs_root: str | Path | None = None, sim: bool = False,
                 faults: Sequence[str] = (), start_timeout_s: float = 60.0,
                 sim_clock: SimClock | None = None, preview: bool = False) -> None:
        mine, theirs = socket.socketpair()
        self.process: MotionProcessHandle = start_motion_process(theirs)
        theirs.close()
        self.conn = Connection(mine.detach())
        self._clock: Callable[[], float] = time.perf_counter if sim_clock is None else sim_clock.now
        """The motion process's clock (E-stops are stamped on it)."""
        self._sim = sim_clock
        """The simulated clock, which holds time until the E-stops sent are taken."""
        ctx = RunContext(port, sim, tuple(faults), None if logs_root is None else str(logs_root),
                         None if sim_clock is None else sim_clock.path, preview)
        self.conn.send(Start(profile, ctx, None if cache_dir is None else str(cache_dir)))
        self._lock = threading.Lock()
        self._replies: dict[int, Reply[object] | Failed] = {}
        self._cond = threading.Condition()
        self._next_id = 1
        self._ended_motion = 0
        """Id of the last motion request whose result came back (0: none): E-stops say it."""
        self._closed = False
        self._lost = ""
        self.homed = False
        """Whether the motion process has the wrist homed (from its latest answer): the one
        flag; the front ends read it, never keep their own."""
        self.on_sample: Callable[[Sample], None] | None = None
        self.on_planned: Callable[[Planned], None] | None = None
        """Told what the runtime is about to run (its duration, approach included) before
        the motion's first cycle (called on the reading thread: keep it short)."""
        self.telemetry_dropped = 0
        """Samples the motion process left out of the telemetry because this client read
        too slowly (the run logs have them all)."""
        self._telemetry: queue.SimpleQueue[Telemetry | threading.Event | None] = queue.SimpleQueue()
        if not self.conn.poll(start_timeout_s):
            self.close()
            raise MotionProcessLostError("the motion process did not start")
        first = self.conn.recv()
        if isinstance(first, Failed):
            self.close()
            raise _error(first)
        self.pid = int(first.value)
        threading.Thread(target=self._dispatch, daemon=True, name="spm-telemetry-in").start()
        self._reader = threading.Thread(target=self._read, daemon=True, name="spm-motion-client")
        self._reader.start()
        self._moving = threading.Event()
        self._beat = threading.Thread(target=self._heartbeat, daemon=True, name="spm-heartbeat")
        self._beat.start()

    # --- plumbing ---------------------------------------------------------------------
    def _send(self, msg: object) -> None:
        with self._lock:
            if self._lost:
                raise MotionProcessLostError(self._lost)
            try:
                self.conn.send(msg)
            except (OSError, EOFError, BrokenPipeError):
                self._mark_lost()
                raise MotionProcessLostError(self._lost) from None

    def _mark_lost(self) -> None:
        code = self.process.poll()
        self._lost = self._lost or (
            "the motion process is gone" + (f" (exit code {code})" if code is not None else "")
            + "; the servos' Bus Watchdog stops them if a motion was running")
        with self._cond:
            self._cond.notify_all()

    def _read(self) -> None:
        while True:
            try:
                msg = self.conn.recv()
            except (EOFError, OSError):
                if not self._closed:
                    self._mark_lost()
                return
            if isinstance(msg, Planned):
                cb = self.on_planned
                if cb is not None:
                    with contextlib.suppress(Exception):
                        cb(msg)
                continue
            if isinstance(msg, Telemetry):  # handed on: a slow callback never stops the reading
                self.telemetry_dropped += msg.dropped
                self._telemetry.put(msg)
                continue
            with self._cond:
                if isinstance(msg, (Reply, Failed)):
                    self.homed = msg.homed  # the motion process's own flag, as of this answer
                self._replies[msg.id] = msg
                self._cond.notify_all()

    def _dispatch(self) -> None:
        """Call ``on_sample`` for each sample received (its own thread: a callback that
        waits, e.g. on the 3D view, only delays the callbacks)."""
        while (msg := self._telemetry.get()) is not None:
            if isinstance(msg, threading.Event):  # everything before it was delivered
                msg.set()
                continue
            cb = self.on_sample
            if cb is None:
                continue
            with contextlib.suppress(Exception):
                for sample in msg.samples:
                    cb(sample)

    def _heartbeat(self) -> None:
        while not self._closed and not self._lost:
            if self._moving.wait(0.5) and not self._closed:
                with contextlib.suppress(MotionProcessLostError):
                    self._send(Heartbeat())
                time.sleep(HEARTBEAT_S)

    def _new_id(self) -> int:
        with self._lock:
            rid = self._next_id
            self._next_id += 1
        return rid

    def _call(self, make: Callable[[int], Request[T]], timeout_s: float | None,
              rid: int | None = None) -> T:
        """Send the request ``make`` builds with ``rid`` (default: the next id); its reply's
        value (the type the request names), or the error its :class:`Failed` stands for."""
        rid = self._new_id() if rid is None else rid
        self._send(make(rid))
        t_end = None if timeout_s is None else time.monotonic() + timeout_s
        with self._cond:
            while rid not in self._replies:
                if self._lost:
                    raise MotionProcessLostError(self._lost)
                left = None if t_end is None else t_end - time.monotonic()
                if left is not None and left <= 0:
                    raise MotionProcessLostError(f"the motion process did not answer within {timeout_s:g} s")
                self._cond.wait(0.1 if left is None else min(0.1, left))
            msg = self._replies.pop(rid)
        if isinstance(msg, Failed):
            raise _error(msg)
        return cast("T", msg.value)

    # --- operations ---------------------------------------------------------------------
    def ping_all(self) -> list[ServoStatus]:
        return list(self._call(lambda i: Ping(i), REQUEST_TIMEOUT_S))

    def read_position(self) -> NDArray[np.float64]:
        """Measured θ (deg), read with set-up retries."""
        return self._call(lambda i: ReadPosition(i), REQUEST_TIMEOUT_S)

    def status(self) -> ServoHealth:
        """Every joint's health (:class:`~spm_console.motion.servo_tools.ServoHealth`);
        refused (BadInputError) while a motion runs."""
        return self._call(lambda i: Status(i), REQUEST_TIMEOUT_S)

    def set_torque(self, joint: int, on: bool) -> ServoHealth:
        """Torque Enable of one joint (1-based; "on" holds it where it is), then the health
        read after it; refused while a motion runs."""
        return self._call(lambda i: Torque(i, joint, on), REQUEST_TIMEOUT_S)

    def reboot(self, joint: int) -> ServoHealth:
        """REBOOT one joint's servo (clears a hardware error; torque comes back off), then
        the health read after it; refused while a motion runs."""
        return self._call(lambda i: Reboot(i, joint), REQUEST_TIMEOUT_S)

    def _motion(self, make: Callable[[int], Request[T]],
                on_sample: Callable[[Sample], None] | None) -> T:
        self.on_sample = on_sample
        rid = self._new_id()
        self._moving.set()
        try:
            return self._call(make, None, rid)
        finally:
            self._moving.clear()
            delivered = threading.Event()  # the motion's last samples reach on_sample first
            self._telemetry.put(delivered)
            delivered.wait(5.0)
            self.on_sample = None
            # its result is in and its samples delivered: a later E-stop is for a later motion
            # (the front end marks the wrist idle at once: an E-stop sent while this waited was
            # for this motion, and the motion process lets it go)
            self._ended_motion = rid

    def home(self, on_sample: Callable[[Sample], None] | None = None) -> HomingResult:
        return self._motion(lambda i: Home(i), on_sample)

    def execute(self, plan: Plan, on_sample: Callable[[Sample], None] | None = None,
                approach_tolerance_deg: float | None = None, skip_homing: str = "",
                source: str | None = None, approach: bool = True) -> ExecutionResult:
        """Execute ``plan`` (refused unless this motion process homed the wrist, or
        ``skip_homing`` says why the operator overrides that; ``approach`` False: refused
        unless the wrist is at its start)."""
        return self._motion(lambda i: Execute(i, plan, approach_tolerance_deg, skip_homing, source,
                                              approach), on_sample)

    def verify(self, plan: Plan, log_kind: str = "") -> PlanCheck:
        """The plan verified by the motion process as :meth:`execute` will verify it, moving
        nothing (PlanRefusedError, exit 26, when refused; ``log_kind``: the refusal also
        leaves a run folder of that kind); refused while a motion runs."""
        check = self._call(lambda i: Verify(i, plan, log_kind), VERIFY_TIMEOUT_S)
        assert isinstance(check, PlanCheck)
        return check

    def nudge(self, moves: tuple[tuple[int, float], ...], speed_degps: float) -> NudgeResult:
        """Commissioning: servos by id to small offsets from their rest (deg), the others
        holding (:mod:`~spm_console.motion.nudge`); E-stops reach it."""
        result = self._motion(lambda i: Nudge(i, moves, speed_degps), None)
        if not isinstance(result, NudgeResult):
            raise BusError("commission: the motion process answered a nudge with nothing")
        return result

    def end_nudging(self, hold: bool = False) -> None:
        """The servos' PWM Limits restored after commissioning's nudges; torque off, or with
        ``hold`` (after an E-stop, or once a nudge began: the jig is off) on again, holding
        where they were."""
        self._motion(lambda i: Nudge(i, release=True, hold=hold), None)

    def query(self, q: BusQuery) -> BusReport:
        """A bus diagnostic by servo id (BusQuery -> BusReport); refused while moving."""
        return self._call(lambda i: Query(i, q), REQUEST_TIMEOUT_S)

    def follow(self, timed: TimedTargets | None = None,
               initial_deg: Sequence[float] | NDArray[np.float64] | None = None, deadman_s: float | None = None,
               on_sample: Callable[[Sample], None] | None = None, skip_homing: str = "",
               source: str | None = None) -> FollowOutcome:
        """Follow timed targets, or live ones sent with :meth:`set_target` (see
        :class:`~spm_console.motion.protocol.Follow`); blocks until the run ends."""
        init: tuple[float, float, float] | None = None
        if initial_deg is not None:
            a, b, c = (float(x) for x in initial_deg)
            init = (a, b, c)
        return self._motion(lambda i: Follow(i, timed, init, deadman_s, skip_homing, source),
                            on_sample)

    def set_target(self, theta_deg: Sequence[float] | NDArray[np.float64]) -> None:
        """A new live target (deg) for the following under way (any thread)."""
        a, b, c = (float(x) for x in theta_deg)
        self._send(SetTarget((a, b, c)))

    def end_follow(self) -> None:
        """The live source is done: the follower settles on the current target and ends."""
        self._send(EndFollow())

    def estop(self, reason: str, by_signal: bool = False) -> None:
        """The message; a signal to the process is the second path when the pipe is gone.

        Safe in a signal handler: when the handler interrupted this thread in the middle of
        a send, the E-stop goes out from a helper thread as soon as that send is done."""
        if self._sim is not None:  # counted before the stamp: time waits for it from then
            self._sim.stop_sent()
        msg = EStop(reason, self._clock(), by_signal, self._ended_motion)
        if self._lock.acquire(blocking=False):
            self._lock.release()
            self._send_estop(msg)
        else:
            threading.Thread(target=self._send_estop, args=(msg,), daemon=True,
                             name="spm-estop").start()

    def _send_estop(self, msg: EStop) -> None:
        try:
            self._send(msg)
            return
        except MotionProcessLostError:
            if self._sim is not None:
                self._sim.stop_sent(-1)  # not sent: time does not wait for it
        if self.process.poll() is None:
            with contextlib.suppress(OSError):
                self.process.send_signal(ESTOP_SIGNAL)

    def close(self, timeout_s: float = 5.0) -> None:
        if self._closed:
            return
        with contextlib.suppress(MotionProcessLostError, OSError):
            self._send(Close())
        self._closed = True
        self._telemetry.put(None)
        try:
            self.process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.process.terminate()
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.process.wait(2.0)
        with contextlib.suppress(OSError):
            self.conn.close()


def _error(msg: Failed) -> SpmError:
    return error_for(msg.exit_code, msg.message, msg.reason)


class EstopRelay:
    """An E-stop for work that opens motion processes one after another (commissioning: one
    per stage), held by a front end instead of a session. Pressed from any thread (a key, a
    signal handler: plain attribute writes, no lock), it stops the nudge or move running in
    the process attached now, and every later :meth:`attach` or :meth:`check` refuses."""

    def __init__(self, what: str) -> None:
        self.what = what
        """The work's name, for the refusal ("commission")."""
        self.reason = ""
        """Why it was pressed ("" until then)."""
        self._client: MotionClient | None = None

    def attach(self, client: MotionClient) -> None:
        """The motion process the next stage runs in; refused with
        :class:`~spm_console.errors.BusError` when the switch was pressed already."""
        self._client = client
        self.check()

    def detach(self) -> None:
        """That motion process is closing."""
        self._client = None

    def estop(self, reason: str, by_signal: bool = False) -> bool:
        """Stop the running nudge or move (the motion process keeps an E-stop that comes
        between two of them for the next one); True."""
        if not self.reason:
            self.reason = reason
        client = self._client
        if client is not None:
            client.estop(reason, by_signal)
        return True

    def check(self) -> None:
        """Raise :class:`~spm_console.errors.BusError` once the switch was pressed."""
        if self.reason:
            raise BusError(f"{self.what} stopped: {self.reason}; the wrist holds or is "
                           "torque off. Nothing was written")
