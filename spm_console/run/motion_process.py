"""The servo loop in its own OS process, owning the serial port; front ends are its clients.

:class:`MotionClient` starts the child (``multiprocessing`` spawn: a fresh interpreter, no
UI thread, no GC pressure from the front end) and talks to it over one pipe with the typed
messages of :mod:`spm_console.run.motion_protocol`: requests (ping, read, home, execute,
E-stop, heartbeat, close) in; replies, throttled telemetry and results out.

In the child, :func:`serve` opens the bus, loads this profile's workspace (the runtime
verifies every motion against it; loaded on the first motion) and answers requests; a motion runs in a worker thread
(real-time scheduling, see :mod:`spm_console.realtime`) while the main thread keeps
reading the pipe, so an E-stop reaches the executor within one period. **Deadman:** during
a motion the client sends a heartbeat every :data:`HEARTBEAT_S`; when none arrives for
:data:`DEADMAN_S` (or the pipe closes because the client died) the loop E-stops — the
profile's stop action, "client lost" in the log. If the child itself dies, the servos'
Bus Watchdog (armed during every run) stops them and the client raises
:class:`MotionProcessLostError` (exit 27). Degrees and seconds.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

from spm_console.errors import BusError, MotionProcessLostError, SpmError, error_for
from spm_console.profile import Profile
from spm_console.run.motion_protocol import (
    Close,
    EStop,
    Execute,
    Failed,
    Heartbeat,
    Home,
    Ping,
    ReadPosition,
    Reply,
    Request,
    Telemetry,
)
from spm_console.run.operator_runs import RunContext, run_execute, run_home
from spm_console.run.sample import Sample

#: Client heartbeat period during a motion, s.
HEARTBEAT_S = 0.1
#: No heartbeat for this long during a motion: the loop holds ("client lost"), s (50 periods
#: of 20 ms; 10 missed heartbeats). A client that dies closes the pipe and is caught at once;
#: this bounds a client that hangs, with room for a front end starved by a loaded machine
#: (every motion it lets continue was verified before torque-on).
DEADMAN_S = 1.0
#: Telemetry to the client at most this often, s (the loop itself runs every Ts).
TELEMETRY_S = 0.05
#: How long a request other than a motion may take before the child counts as hung, s.
REQUEST_TIMEOUT_S = 30.0


# ---------------------------------------------------------------------------------- child
class _Server:
    """State of the child: bus, workspace, the motion under way."""

    def __init__(self, conn: Connection, profile: Profile, ctx: RunContext,
                 cache_dir: str | None) -> None:
        from spm_console.devices.bus import open_bus

        self.conn = conn
        self.profile = profile
        self.ctx = ctx
        self.cache_dir = cache_dir
        self._workspace: Any = None
        self.bus = open_bus(profile, ctx.port)
        self.send_lock = threading.Lock()
        self.executor: Any = None
        self.motion: threading.Thread | None = None
        self.pending_estop = ""
        self.pending_clock: float | None = None
        self.last_heartbeat = time.monotonic()
        self.client_lost = ""

    def send(self, msg: object) -> None:
        with self.send_lock, contextlib.suppress(OSError, EOFError, BrokenPipeError):
            self.conn.send(msg)

    # --- requests ---------------------------------------------------------------------
    def handle(self, req: Request) -> None:
        if isinstance(req, Heartbeat):
            self.last_heartbeat = time.monotonic()
        elif isinstance(req, EStop):
            self.estop(req.reason, req.sent_clock)
        elif isinstance(req, (Home, Execute)):
            if self.motion is not None and self.motion.is_alive():
                self.send(Failed(req.id, BusError("a motion is already running").message, 4))
                return
            self.last_heartbeat = time.monotonic()
            self.motion = threading.Thread(target=self._motion, args=(req,), daemon=True,
                                           name="spm-motion")
            self.motion.start()
        elif isinstance(req, (Ping, ReadPosition)):
            self._answer(req)

    def _answer(self, req: Ping | ReadPosition) -> None:
        try:
            if isinstance(req, ReadPosition):
                from spm_console.devices.base import CommError, read_position_settled

                try:
                    value: object = read_position_settled(self.bus, 3)
                except (CommError, OSError) as exc:
                    raise BusError(f"no position reply from the servos after 3 tries ({exc})") from None
            else:
                value = self.ping()
            self.send(Reply(req.id, value))
        except SpmError as exc:
            self.send(Failed(req.id, exc.message, int(exc.exit_code)))

    def ping(self) -> list[Any]:
        from dataclasses import replace

        from spm_console.devices.base import CommError

        volt = "present_input_voltage" if self.profile.bus.protocol == "2.0" else "present_voltage"
        out = []
        for st in self.bus.ping_all():
            with contextlib.suppress(CommError, OSError, KeyError, SpmError):  # informative only
                st = replace(st, temperature_c=float(self.bus.read(st.id, "present_temperature")),
                             voltage_v=0.1 * float(self.bus.read(st.id, volt)))
            out.append(st)
        return out

    # --- motion -----------------------------------------------------------------------
    @property
    def workspace(self) -> Any:
        """This profile's workspace (cache, or built on first use): every motion is verified
        against it."""
        if self._workspace is None:
            from spm_console.workspace_cache import load_or_build

            self._workspace, _ = load_or_build(self.profile, cache_dir=self.cache_dir)
        return self._workspace

    def estop(self, reason: str, sent_clock: float | None = None) -> None:
        if not self.pending_estop:
            self.pending_estop, self.pending_clock = reason, sent_clock
        if self.executor is not None:
            self.executor.request_estop(self.pending_estop, self.pending_clock)

    def _attach(self, ex: Any) -> None:
        self.executor = ex
        if self.pending_estop:
            ex.request_estop(self.pending_estop, self.pending_clock)

    def _motion(self, req: Home | Execute) -> None:

        last = [0.0]
        batch: list[Sample] = []

        def flush() -> None:
            if batch:
                self.send(Telemetry(tuple(batch)))
                batch.clear()

        def on_sample(s: Sample) -> None:
            batch.append(s)
            now = time.monotonic()
            if now - last[0] >= TELEMETRY_S:
                last[0] = now
                flush()

        try:
            if isinstance(req, Home):
                value: object = run_home(self.profile, self.bus, self.workspace, self.ctx,
                                         on_sample, self._attach)
            else:
                value = run_execute(self.profile, self.bus, self.workspace, req.plan, self.ctx,
                                    on_sample, self._attach, req.approach_tolerance_deg)
            flush()
            self.send(Reply(req.id, value))
        except SpmError as exc:
            flush()
            self.send(Failed(req.id, exc.message, int(exc.exit_code)))
        except Exception as exc:  # a bug: the executor already left the wrist holding
            self.send(Failed(req.id, f"internal error in the motion process: {exc!r}", 1))
        finally:
            self.executor = None
            self.pending_estop, self.pending_clock = "", None

    def moving(self) -> bool:
        return self.motion is not None and self.motion.is_alive()

    def deadman(self, stop: threading.Event) -> None:
        """E-stop when the client's heartbeat stops during a motion."""
        while not stop.wait(HEARTBEAT_S / 2):
            if self.moving() and time.monotonic() - self.last_heartbeat > DEADMAN_S:
                self.estop(f"client lost: no heartbeat for more than {DEADMAN_S * 1e3:.0f} ms")


@dataclass(frozen=True)
class Start:
    """The first message to the child: what to serve."""

    profile: Profile
    ctx: RunContext
    cache_dir: str | None


def serve(conn: Connection, start: Start) -> None:
    """The child's main loop (see module docstring)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the client decides; Ctrl-C reaches it first
    try:
        server = _Server(conn, start.profile, start.ctx, start.cache_dir)
    except SpmError as exc:
        conn.send(Failed(0, exc.message, int(exc.exit_code)))
        return
    conn.send(Reply(0, os.getpid()))
    signal.signal(signal.SIGUSR1, lambda *_: server.estop("E-stop signal to the motion process"))
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
        with contextlib.suppress(OSError, SpmError):
            server.bus.close()


# --------------------------------------------------------------------------------- client
class MotionClient:
    """The front end's handle on the motion process (thread-safe; one motion at a time)."""

    def __init__(self, profile: Profile, port: str, *, cache_dir: str | Path | None = None,
                 logs_root: str | Path | None = None, sim: bool = False,
                 faults: Sequence[str] = (), start_timeout_s: float = 60.0) -> None:
        mine, theirs = socket.socketpair()
        self.process = subprocess.Popen(
            [sys.executable, "-m", "spm_console.run.motion_process", "--fd", str(theirs.fileno())],
            pass_fds=(theirs.fileno(),), stdin=subprocess.DEVNULL)
        theirs.close()
        self.conn = Connection(mine.detach())
        ctx = RunContext(port, sim, tuple(faults), None if logs_root is None else str(logs_root))
        self.conn.send(Start(profile, ctx, None if cache_dir is None else str(cache_dir)))
        self._lock = threading.Lock()
        self._replies: dict[int, Reply | Failed] = {}
        self._cond = threading.Condition()
        self._next_id = 1
        self._closed = False
        self._lost = ""
        self.on_sample: Callable[[Sample], None] | None = None
        if not self.conn.poll(start_timeout_s):
            self.close()
            raise MotionProcessLostError("the motion process did not start")
        first = self.conn.recv()
        if isinstance(first, Failed):
            self.close()
            raise _error(first)
        self.pid = int(first.value)
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
            if isinstance(msg, Telemetry):
                cb = self.on_sample
                if cb is not None:
                    with contextlib.suppress(Exception):
                        for sample in msg.samples:
                            cb(sample)
                continue
            with self._cond:
                self._replies[msg.id] = msg
                self._cond.notify_all()

    def _heartbeat(self) -> None:
        while not self._closed and not self._lost:
            if self._moving.wait(0.5) and not self._closed:
                with contextlib.suppress(MotionProcessLostError):
                    self._send(Heartbeat())
                time.sleep(HEARTBEAT_S)

    def _call(self, make: Callable[[int], Request], timeout_s: float | None) -> Any:
        with self._lock:
            rid = self._next_id
            self._next_id += 1
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
        return msg.value

    # --- operations ---------------------------------------------------------------------
    def ping_all(self) -> list[Any]:
        return list(self._call(lambda i: Ping(i), REQUEST_TIMEOUT_S))

    def read_position(self) -> Any:
        return self._call(lambda i: ReadPosition(i), REQUEST_TIMEOUT_S)

    def _motion(self, make: Callable[[int], Request], on_sample: Callable[[Sample], None] | None) -> Any:
        self.on_sample = on_sample
        self._moving.set()
        try:
            return self._call(make, None)
        finally:
            self._moving.clear()
            self.on_sample = None

    def home(self, on_sample: Callable[[Sample], None] | None = None) -> Any:
        return self._motion(lambda i: Home(i), on_sample)

    def execute(self, plan: Any, on_sample: Callable[[Sample], None] | None = None,
                approach_tolerance_deg: float | None = None) -> Any:
        return self._motion(lambda i: Execute(i, plan, approach_tolerance_deg), on_sample)

    def estop(self, reason: str) -> None:
        """The message; a signal to the process is the second path when the pipe is gone."""
        try:
            self._send(EStop(reason, time.perf_counter()))
            return
        except MotionProcessLostError:
            pass
        if self.process.poll() is None:
            with contextlib.suppress(OSError):
                os.kill(self.process.pid, signal.SIGUSR1)

    def close(self, timeout_s: float = 5.0) -> None:
        if self._closed:
            return
        with contextlib.suppress(MotionProcessLostError, OSError):
            self._send(Close())
        self._closed = True
        try:
            self.process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.process.terminate()
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.process.wait(2.0)
        with contextlib.suppress(OSError):
            self.conn.close()


def _error(msg: Failed) -> SpmError:
    return error_for(msg.exit_code, msg.message)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m spm_console.run.motion_process --fd N``: serve the client on fd N."""
    parser = argparse.ArgumentParser(description="spm_console motion process (started by a client)")
    parser.add_argument("--fd", type=int, required=True)
    args = parser.parse_args(argv)
    conn = Connection(args.fd)
    try:
        start = conn.recv()
    except (EOFError, OSError):
        return 0
    serve(conn, start)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
