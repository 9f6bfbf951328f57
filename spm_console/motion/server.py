"""The servo loop in its own OS process, owning the serial port; front ends are its clients.

:class:`~spm_console.services.client.MotionClient` starts this module as a child
(``python -m spm_console.motion.server``: a fresh interpreter, no UI thread, no GC
pressure from the front end) and talks to it over one socket pair with the typed messages of
:mod:`spm_console.motion.protocol`: requests (ping, read, servo status, torque per
joint, reboot, home, execute, E-stop, heartbeat, close) in; replies, throttled telemetry and results out.

In the child, :func:`serve` opens the bus, loads this profile's workspace (the runtime
verifies every motion against it; loaded on the first motion) and answers requests; a motion runs in a worker thread
(real-time scheduling, see :mod:`spm_console.system.realtime`) while the main thread keeps
reading the pipe, so an E-stop reaches the executor within one period. **Deadman:** during
a motion the client sends a heartbeat every :data:`HEARTBEAT_S`; when none arrives for
:data:`DEADMAN_S` (or the pipe closes because the client died) the loop E-stops — the
profile's stop action, "client lost" in the log. If the child itself dies, the servos'
Bus Watchdog (armed during every run) stops them and the client raises
:class:`MotionProcessLostError` (exit 27). Degrees and seconds.

The answers to requests that move nothing, the telemetry sender and the garbage collector kept
quiet during a motion are in :mod:`spm_console.motion.serving`.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from types import FrameType
from typing import TYPE_CHECKING

from spm_console.config.schema import Profile
from spm_console.devices.base import CommError
from spm_console.errors import RefusedError, SpmError
from spm_console.motion.executor import Executor
from spm_console.motion.follow.target_feed import TargetFeed
from spm_console.motion.nudge import NudgeState, release, run_nudge
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
    SetTarget,
    Status,
    Torque,
    ToServer,
    Verify,
)
from spm_console.motion.runs import (
    RunContext,
    SampleCallback,
    run_execute,
    run_home,
)
from spm_console.motion.segments import Segment
from spm_console.motion.serving.idle import IdleServer
from spm_console.motion.serving.quiet_gc import QuietGc
from spm_console.motion.serving.telemetry import TelemetryOut
from spm_console.motion.stop_action import PendingStop
from spm_console.refusals import Refusal
from spm_console.system.cpus import place_on_loop_cpu
from spm_console.system.realtime import HELPER_PRIORITY, normal_priority, quick_gil_handoff, request_realtime
from spm_console.system.signals import STOP_SIGNALS

if TYPE_CHECKING:  # the following run loads scipy (~1 s): imported after the first answer
    from spm_console.motion.follow.run import FollowOutcome

#: Client heartbeat period during a motion, s.
HEARTBEAT_S = 0.1
#: No heartbeat for this long during a motion: the loop holds ("client lost"), s (50 periods
#: of 20 ms; 10 missed heartbeats). A client that dies closes the pipe and is caught at once;
#: this bounds a client that hangs, with room for a front end starved by a loaded machine
#: (every motion it lets continue was verified before torque-on).
DEADMAN_S = 1.0
#: How long a request other than a motion may take before the child counts as hung, s.
REQUEST_TIMEOUT_S = 30.0


# ---------------------------------------------------------------------------------- child
class _Server(IdleServer):
    """State of the child: bus, workspace, the motion under way."""

    def __init__(self, conn: Connection, profile: Profile, ctx: RunContext,
                 cache_dir: str | None) -> None:
        super().__init__(conn, profile, ctx, cache_dir)
        self.motion: threading.Thread | None = None
        self.busy = threading.Event()
        """A motion runs: set when it is accepted, cleared before its result is sent (so the
        client's next request never finds the motion still winding down)."""
        self.stop = PendingStop()
        """The E-stop held for the motion under way (or the next one)."""
        self.last_heartbeat = time.monotonic()
        self.signals: list[str] = []
        """Terminating signals to this process not yet acted on (left by its handler)."""
        self.feed: TargetFeed | None = None
        """The target feed of the following under way (None otherwise)."""
        self.nudging = NudgeState()
        """Commissioning's nudges: each servo's rest and saved PWM Limit."""

    # --- requests ---------------------------------------------------------------------
    def handle(self, req: ToServer) -> None:
        if isinstance(req, Heartbeat):
            self.last_heartbeat = time.monotonic()
        elif isinstance(req, EStop):
            self.stop.request(req.reason, req.sent_clock, req.by_signal, req.after)
            sim = self.ctx.clock()
            if sim is not None:
                sim.stop_taken()
        elif isinstance(req, SetTarget):
            feed = self.feed
            if feed is not None:
                with contextlib.suppress(SpmError):  # a malformed target changes nothing
                    feed.set(req.theta_deg)
        elif isinstance(req, EndFollow):
            if self.feed is not None:
                self.feed.end()
        elif isinstance(req, (Home, Execute, Follow)):
            if self.moving():
                self.send(self.refused(req.id, RefusedError(Refusal.MOVING)))
                return
            if isinstance(req, Follow):  # the feed exists before any SetTarget can arrive
                try:
                    self.feed = TargetFeed(req.timed, req.initial_deg, req.deadman_s)
                except SpmError as exc:
                    self.stop.ended(req.id)  # an E-stop held for it goes with it
                    self.send(self.refused(req.id, exc))
                    return
            self.last_heartbeat = time.monotonic()
            self.stop.begin(req.id)
            self.busy.set()
            self.motion = threading.Thread(target=self._motion, args=(req,), daemon=True,
                                           name="spm-motion")
            self.motion.start()
        elif isinstance(req, Nudge):
            if self.moving():
                self.send(self.refused(req.id, RefusedError(Refusal.MOVING)))
                return
            self.homed = False  # the wrist leaves where homing put it (or it never was)
            self.last_heartbeat = time.monotonic()
            self.stop.begin(req.id)
            self.busy.set()
            self.motion = threading.Thread(target=self._nudge, args=(req,), daemon=True,
                                           name="spm-nudge")
            self.motion.start()
        elif isinstance(req, (Ping, ReadPosition, Status, Torque, Reboot, Query, Verify)):
            if self.moving():  # the loop owns every bus cycle while the wrist moves
                self.send(self.refused(req.id, RefusedError(Refusal.MOVING)))
                return
            self._answer(req)

    # --- motion -----------------------------------------------------------------------
    def estop(self, reason: str, by_signal: bool = False) -> None:
        """This process's own E-stop (a signal, the deadman) of the motion under way, if any."""
        self.stop.request(reason, by_signal=by_signal)

    def _planned(self, segments: Sequence[Segment]) -> None:
        self.send(Planned(sum((s.plan.N + 1) * s.plan.Ts for s in segments),
                          tuple(s.phase for s in segments)))

    def _attach(self, ex: Executor) -> None:
        ex.on_planned = self._planned
        self.stop.attach(ex)

    def _motion(self, req: Home | Execute | Follow) -> None:
        normal_priority()  # set-up may load the workspace; the executor raises the loop itself
        out = TelemetryOut(self.send)
        on_sample = out.put

        result: Reply[object] | Failed
        quiet_gc = QuietGc()
        try:
            _ = self.workspace  # loaded (or built) before the loop, at normal priority
            quiet_gc.start()
            if isinstance(req, Home):
                homing = run_home(self.profile, self.bus, self.workspace, self.ctx,
                                  on_sample, self._attach)
                self.homed = homing.execution.ok
                result = Reply(req.id, homing)
            elif isinstance(req, Follow):
                result = Reply(req.id, self._follow(req, on_sample))
            else:
                result = Reply(req.id, run_execute(
                    self.profile, self.bus, self.workspace, req.plan, self.ctx, on_sample,
                    self._attach, req.approach_tolerance_deg, homed=self.homed,
                    skip_homing=req.skip_homing, source=req.source, approach=req.approach))
        except SpmError as exc:
            result = self.refused(req.id, exc)
        except Exception as exc:  # a bug: the executor already left the wrist holding
            result = Failed(req.id, f"internal error in the motion process: {exc!r}", 1)
        finally:
            quiet_gc.stop()
            out.close()
            self.feed = None
            self.stop.ended(req.id)
            self.busy.clear()
        self.send(result)

    def _nudge(self, req: Nudge) -> None:
        """A commissioning nudge (or its release) in the motion thread: E-stops reach it."""
        result: Reply[object] | Failed
        try:
            if req.release:
                release(self.bus, self.nudging, req.hold)
                result = Reply(req.id, None)
            else:
                result = Reply(req.id, run_nudge(self.bus, self.nudging, req.moves,
                                                 req.speed_degps, lambda: self.stop.reason,
                                                 **self.ctx.timing()))
        except SpmError as exc:
            result = self.refused(req.id, exc)
        except Exception as exc:  # a bug: hold where the servos are if the bus answers
            with contextlib.suppress(Exception):
                self.bus.hold()
            result = Failed(req.id, f"internal error in the motion process: {exc!r}", 1)
        finally:
            self.stop.ended(req.id)
            self.busy.clear()
        self.send(result)

    def _follow(self, req: Follow, on_sample: SampleCallback) -> FollowOutcome:
        from spm_console.motion.follow.run import run_follow

        assert self.feed is not None  # made by handle() before the motion thread starts
        return run_follow(self.profile, self.bus, self.workspace, self.feed, self.ctx, on_sample,
                          self._attach, homed=self.homed, skip_homing=req.skip_homing,
                          source=req.source)

    def moving(self) -> bool:
        return self.busy.is_set()

    def deadman(self, stop: threading.Event) -> None:
        """E-stop when the client's heartbeat stops during a motion."""
        request_realtime(HELPER_PRIORITY)
        while not stop.wait(HEARTBEAT_S / 2):
            while self.signals:  # what the signal handlers left (see _estop_on_signals)
                name = self.signals.pop(0)
                if name == ESTOP_SIGNAL.name:  # the client's E-stop when its pipe is gone
                    self.estop("E-stop signal to the motion process")
                else:
                    self.estop(f"signal {name} to the motion process", by_signal=True)
            if self.moving() and time.monotonic() - self.last_heartbeat > DEADMAN_S:
                self.estop(f"client lost: no heartbeat for more than {DEADMAN_S * 1e3:.0f} ms")


def _warm_up() -> None:
    """Import what only a motion needs (the Kalman filters load scipy.stats: ~1 s), after
    the process has announced itself (its client goes on starting meanwhile) and before the
    first request is read: no import ever runs beside a bus transaction or the servo loop
    (an import can hold the interpreter's lock for longer than a reply timeout). At normal
    priority: the serving thread's real-time priority is taken again afterwards."""
    normal_priority()
    import filterpy.kalman  # noqa: F401

    import spm_console.motion.follow.run  # noqa: F401


@dataclass(frozen=True)
class Start:
    """The first message to the child: what to serve."""

    profile: Profile
    ctx: RunContext
    cache_dir: str | None


def _estop_on_signals(server: _Server | None) -> None:
    """What a terminating signal sent to this process itself does.

    This process runs in a session of its own (:class:`MotionClient` starts it so): a signal to
    the front end's process group or terminal (Ctrl-C, Ctrl-\\, the terminal closing,
    ``kill -- -PGID``, ``timeout``) never reaches it; the front end E-stops through the
    connection. A signal sent here directly (``kill PID``, a service manager stopping every
    process of its unit) E-stops the motion under way (the profile's stop action, logged) and
    ends nothing else: the process keeps serving until its client closes the connection, so the
    stop is always written and the log closed. Before ``server`` exists the signals are ignored.
    """
    if server is None:
        for sig in STOP_SIGNALS:
            signal.signal(sig, signal.SIG_IGN)
        return

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        # no lock here: the handler runs in the main thread between two bytecodes, maybe
        # inside Event.set of the very E-stop it would request (a client's E-stop and a
        # service stop's SIGTERM arrive together), which would wait for itself for ever. The
        # deadman thread requests the E-stop within HEARTBEAT_S / 2 (list.append takes none).
        # The client's own E-stop signal (ESTOP_SIGNAL, when its pipe is gone) goes the same way.
        server.signals.append(signal.Signals(signum).name)

    for sig in STOP_SIGNALS:
        signal.signal(sig, on_signal)


def serve(conn: Connection, start: Start) -> None:
    """The child's main loop (see module docstring)."""
    _estop_on_signals(None)  # the client decides while this process starts
    request_realtime(HELPER_PRIORITY)  # this thread reads the pipe: see realtime.HELPER_PRIORITY
    quick_gil_handoff()  # the loop thread gets the GIL within ~0.5 ms of asking
    try:
        server = _Server(conn, start.profile, start.ctx, start.cache_dir)
    except SpmError as exc:
        conn.send(Failed(0, exc.message, int(exc.exit_code)))
        return
    conn.send(Reply(0, os.getpid()))
    sim = start.ctx.clock()
    if sim is not None:  # this thread reads the E-stops: its own waits do not hold time for them
        sim.takes_stops()
    _estop_on_signals(server)
    signal.signal(ESTOP_SIGNAL, lambda *_: server.signals.append(ESTOP_SIGNAL.name))
    _warm_up()
    request_realtime(HELPER_PRIORITY)
    stop = threading.Event()
    threading.Thread(target=server.deadman, args=(stop,), daemon=True, name="spm-deadman").start()
    try:
        while True:
            try:
                req = conn.recv()
            except (EOFError, OSError):
                if server.moving():
                    server.estop("client lost: its connection closed")
                break
            if isinstance(req, Close):
                break
            server.handle(req)
    finally:
        stop.set()
        if server.motion is not None:
            server.estop("motion process closing")
            server.motion.join(timeout=5.0)
        # its front end left mid-commissioning: PWM Limits back, the wrist holding where it is
        # (a bus that does not answer is left as it is: nothing else can reach it)
        if server.nudging.saved_pwm:
            with contextlib.suppress(CommError, OSError, SpmError):
                release(server.bus, server.nudging, hold=True)
        with contextlib.suppress(OSError, SpmError):
            server.bus.close()


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m spm_console.motion.server --fd N``: serve the client on fd N."""
    parser = argparse.ArgumentParser(description="spm_console motion process (started by a client)")
    parser.add_argument("--fd", type=int, required=True)
    args = parser.parse_args(argv)
    place_on_loop_cpu()  # before any thread starts: see spm_console.system.cpus
    conn = Connection(args.fd)
    try:
        start = conn.recv()
    except (EOFError, OSError):
        return 0
    serve(conn, start)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
