"""Emulated servo bus: three MX-106 behind a socket or a pseudo-terminal, faults on demand.

:func:`start_emulator` opens the link (``devices/emulator/endpoint.py``: a Unix-domain
socket by default, port ``unix:PATH``; or a raw pty pair, port the slave's path), builds one
:class:`EmulatedServo` per joint of the profile (its protocol, ids, model number,
tick mapping, servo model) and serves the link from a background thread:
it decodes instruction packets, lets the servos answer with the same bytes a real
servo sends, and applies the injected faults to the replies. The thread sleeps in
``select`` on the link (no busy wait), so it answers as soon as a packet is
complete. Time is ``time.perf_counter()``; ``true_state()`` reports it relative
to the clock start together with the true joint angles and velocities (deg, deg/s).

In simulated time (a :class:`~spm_console.system.simclock.SimClock`), time is the shared
clock's: the bus integrates its servos and wrist only when a request comes in, up to the
instant the clock says, tells the clock when it has answered each request's bytes and when
a held-back reply is due, and writes that reply once the clock reaches it. It never steps on
its own: the same requests at the same simulated instants give the same replies.

Given a :class:`~spm_console.devices.emulator.twin.TrueWrist` (a profile and an as-built file),
the bus serves the wrist as built instead of the one the profile describes: its servos' ids,
Drive Modes and horn offsets, its link arcs, tilt, payload and IMU (whose truth
:meth:`EmulatorHandle.truth` and :meth:`EmulatorHandle.imu_truth` read); it can power on in an
operator's home jig (held at the true home until the first torque-on) and write its truth at
100 Hz (:mod:`~spm_console.devices.emulator.truth_log`).
"""

from __future__ import annotations

import math
import random
import select
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import link_model_of, model_of, servo_model_of
from spm_console.config.schema import Profile
from spm_console.description.mjcf import plant_params
from spm_console.devices.dynamixel import protocol1 as p1
from spm_console.devices.dynamixel import protocol2 as p2
from spm_console.devices.dynamixel.control_table import table_for
from spm_console.devices.dynamixel.tick_map import JointMap, joint_maps
from spm_console.devices.emulator.dispatch import dispatch1, dispatch2
from spm_console.devices.emulator.endpoint import Channel, Link, open_endpoint
from spm_console.devices.emulator.faults import FaultSpec
from spm_console.devices.emulator.plant_joint import PlantJoint
from spm_console.devices.emulator.servo import OVERLOAD, EmulatedServo
from spm_console.devices.emulator.truth_log import TruthLog
from spm_console.devices.emulator.twin import TrueWrist
from spm_console.errors import BusError
from spm_console.system.realtime import EMULATOR_PRIORITY, RtGrant, request_realtime
from spm_console.system.simclock import SimClock

if TYPE_CHECKING:  # the physical wrist loads MuJoCo: only a physical plant needs it
    from spm_console.devices.emulator.as_built_parts import WristTruth
    from spm_console.devices.emulator.bno055 import ImuTruth
    from spm_console.devices.emulator.physical import PhysicalWrist

F = NDArray[np.float64]

#: Longest sleep of the serving thread when idle (also the idle recording interval), s.
IDLE_S = 0.005
#: The same with a physical wrist, which steps while idle: a request then finds at most
#: this much of its motion left to integrate before the reply (a few steps, ~0.1 ms).
PHYSICAL_IDLE_S = 0.001
#: How often the serving thread looks at the simulated clock while a reply is held back, s
#: (wall clock).
SIM_POLL_S = 0.0001
#: A partial packet older than this when new bytes arrive is dropped (like the firmware's
#: byte-to-byte timeout), so a garbage header with a huge length cannot hold the line.
GAP_S = 0.01
#: Instructions that read a servo's state (READ and BULK_READ in both protocols, 2.0's SYNC_READ).
_READS = frozenset((p2.Inst.READ, p2.Inst.SYNC_READ, p2.Inst.BULK_READ, p1.Inst.READ, p1.Inst.BULK_READ))


@dataclass
class EmulatorStats:
    """What the emulator did (for tests and the ``emulate`` summary)."""

    instructions: int = 0
    replies: int = 0
    dropped: int = 0
    corrupted: int = 0
    delayed: int = 0
    silenced: int = 0
    """Instructions ignored while the bus is unplugged."""
    rejected_bytes: int = 0
    faults_fired: list[str] = field(default_factory=list)


class EmulatorHandle:
    """A running emulated bus. Use :func:`start_emulator`; ``stop()`` when done."""

    def __init__(self, profile: Profile, faults: Sequence[FaultSpec] = (), record: bool = True,
                 initial_deg: Sequence[float] | None = None, link: Link | None = None, *,
                 truth: TrueWrist | None = None, jig: bool = False,
                 truth_log: TruthLog | None = None, sim: SimClock | None = None) -> None:
        self.profile = profile
        self.sim = sim
        """Simulated time (see the module docstring); None: the wall clock."""
        self._clock: Callable[[], float] = time.perf_counter if sim is None else sim.now
        self.protocol = profile.bus.protocol
        self.true_wrist = truth
        """The wrist as built the bus serves (None: the profile's)."""
        self.maps: list[JointMap] = joint_maps(profile) if truth is None else truth.encoder_maps()
        """Per joint, the servo's id and its count ↔ true θ (deg)."""
        table = table_for(self.protocol)
        if profile.bus.model_number != table.model_number:
            raise BusError(
                f"the emulator serves MX-106 (model {table.model_number} on protocol "
                f"{self.protocol}); the profile expects model {profile.bus.model_number}"
            )
        home = list(profile.home.theta_deg) if truth is None else truth.home_deg
        if (jig or truth_log is not None) and (truth is None or profile.plant.model != "physical"):
            raise BusError("a home jig and a truth log need the physical wrist as built "
                           "([plant] model = \"physical\" and a TrueWrist)")
        if jig and initial_deg is not None:
            raise BusError("a home jig holds the wrist at home: no other power-on angles")
        theta0 = list(initial_deg) if initial_deg is not None else home
        if len(theta0) != 3:
            raise BusError("initial_deg: expected three joint angles")
        rng = np.random.default_rng(profile.emulator.seed)
        tpd = profile.bus.ticks_per_turn / 360.0
        self.wrist = _physical_wrist(profile, theta0, truth)
        """The rigid-body wrist the servos drive (``[plant] model = "physical"``), or None."""
        if jig and self.wrist is not None:
            self.wrist.hold_jig()
        # the servos power on once the wrist is built (MuJoCo's model and the assembly take a
        # tenth of a second or more): the serving thread never starts behind, integrating
        # that time before its first reply
        now = self._clock()
        if self.wrist is not None:
            self.wrist.t = now
        self.t_power_on = now
        """When the servos powered on (``time.perf_counter()`` or the simulated clock), s: the
        truth log's zero."""
        modes = [0, 0, 0] if truth is None else [j.drive_mode for j in truth.joints]
        self.servos = [
            EmulatedServo(table, m.id, servo_model_of(profile).dynamics, m.to_ticks(theta0[i]), now,
                          profile.emulator.noise_deg * tpd, rng, profile.bus.ticks_per_turn,
                          None if self.wrist is None else PlantJoint(self.wrist, i, m),
                          drive_mode=modes[i])
            for i, m in enumerate(self.maps)
        ]
        self._by_id = {s.id: s for s in self.servos}
        self._truth_log = truth_log
        self._record = record
        self._t: list[float] = []
        self._pos: list[list[float]] = []
        self._vel: list[list[float]] = []
        self._reads: list[int] = []
        """Indices of the records whose state answered a read (READ, SYNC_READ, BULK_READ)."""
        self._faults: list[FaultSpec] = []
        self._fired: set[int] = set()
        self._frng = random.Random(profile.emulator.seed + 1)
        self._pending: list[tuple[float, Channel, bytes]] = []
        self.stats = EmulatorStats()
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self.t0 = now
        self.clock_started = False
        """Set by the first torque-on or :meth:`start_clock`: until then only faults at
        t = 0 act (a fault at t > 0 waits for the motion, wherever it was started from)."""
        self.link: Link = link or profile.emulator.link
        self._endpoint = open_endpoint(self.link, p2.Decoder2 if self.protocol == "2.0" else p1.Decoder1)
        self.port: str = self._endpoint.port
        """What a client opens: ``unix:PATH`` for the socket, the pty slave's path."""
        for f in faults:
            self.inject(f)
        self.realtime = RtGrant("normal", "not serving yet")
        """The scheduling the serving thread got."""
        self._thread = threading.Thread(target=self._serve, name="spm-emulator", daemon=True)
        self._thread.start()

    # --- public interface -------------------------------------------------------------

    def start_clock(self) -> None:
        """t = 0 now: fault times (and true_state times) are relative to this instant."""
        with self._lock:
            now = self._clock()
            self._advance(now)
            self.t0 = now
            self.clock_started = True

    def inject(self, fault: FaultSpec) -> None:
        """Add a fault; it fires when the clock reaches ``fault.at_s``."""
        with self._lock:
            self._faults.append(fault)

    def true_state(self) -> dict[str, F]:
        """Recorded truth: 't' (n,) s from clock start, 'position_deg' and 'velocity_degps' (n, 3),
        'read' (n,): the records whose state answered a read instruction."""
        with self._lock:
            self._advance(self._clock())
            t = np.asarray(self._t, float) - self.t0
            pos = np.asarray(self._pos, float).reshape(-1, 3)
            vel = np.asarray(self._vel, float).reshape(-1, 3)
            read = np.zeros(len(t), bool)
            read[self._reads] = True
        return {"t": t, "position_deg": pos, "velocity_degps": vel, "read": read}

    def joint_deg(self) -> F:
        """True joint angles now, deg."""
        with self._lock:
            self._advance(self._clock())
            return np.array([m.to_deg(s.pos) for m, s in zip(self.maps, self.servos, strict=True)])

    def take_peak_current(self) -> F | None:
        """The physical wrist's largest |winding current| per joint (A) since the last call,
        stepped to now; it starts again (None: ideal servos, no current modelled)."""
        with self._lock:
            if self.wrist is None:
                return None
            self._advance(self._clock())
            return self.wrist.take_peak_current()

    def set_joint_deg(self, theta_deg: Sequence[float] | F) -> None:
        """Place the servos at rest at these joint angles (deg)."""
        theta = [float(x) for x in theta_deg]
        if len(theta) != 3:
            raise BusError("set_joint_deg: expected three joint angles")
        with self._lock:
            self._advance(self._clock())
            if self.wrist is not None:
                self.wrist.set_theta(np.radians(theta))
            for m, s, th in zip(self.maps, self.servos, theta, strict=True):
                s.place(m.to_ticks(th))
            self._sample()

    def truth(self) -> WristTruth:
        """The wrist's truth now, stepped to this instant (the physical wrist as built only):
        what its IMU senses, the platform's orientation, θ."""
        with self._lock:
            if self.wrist is None or self.wrist.parts is None:
                raise BusError("only the physical wrist as built carries an IMU")
            self._advance(self._clock())
            return self.wrist.truth()

    def imu_truth(self) -> ImuTruth:
        """What an ideal IMU on the platform senses now: an emulated IMU's truth
        (``EmulatedBno055(handle.imu_truth)``)."""
        return self.truth().imu

    def stop(self) -> None:
        """Stop serving, close the link and the truth log."""
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        self._endpoint.close()
        if self._truth_log is not None:
            with self._lock:
                self._truth_log.close()

    def __enter__(self) -> EmulatorHandle:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.stop()

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    # --- state ------------------------------------------------------------------------

    def _sample(self) -> None:
        if not self._record:
            return
        self._t.append(self.servos[0].t)
        self._pos.append([m.to_deg(s.pos) for m, s in zip(self.maps, self.servos, strict=True)])
        self._vel.append([m.direction * s.vel * 360.0 / m.ticks_per_turn
                          for m, s in zip(self.maps, self.servos, strict=True)])

    def _advance(self, now: float) -> None:
        """Fire due one-shot faults at their exact time, then integrate up to ``now``."""
        for k, f in enumerate(self._faults):
            due = self.t0 + f.at_s
            if k in self._fired or due > now or (f.at_s > 0 and not self.clock_started):
                continue
            self._fired.add(k)
            self.stats.faults_fired.append(str(f))
            if f.kind in ("stall", "hwerror") and f.joint is not None:
                for s in self.servos:
                    s.advance(max(due, s.t))
                s = self.servos[f.joint - 1]
                if f.kind == "stall":
                    s.stall()
                else:
                    s.raise_hardware_error(OVERLOAD)
        if self._truth_log is not None:
            self._log_truth(now)
        for s in self.servos:
            s.advance(now)
        self._sample()

    def _log_truth(self, now: float) -> None:
        """The truth log's rows due by ``now``, each at its instant (the wrist stepped there)."""
        log, wrist = self._truth_log, self.wrist
        if log is None or wrist is None:
            return
        while log.open and self.t_power_on + log.next_s <= now:
            wrist.advance(self.t_power_on + log.next_s)
            truth = wrist.truth()
            log.write(truth.t_s - self.t_power_on, truth.platform_quat_wxyz, truth.theta_deg)

    def _active(self, kind: str, now: float) -> list[FaultSpec]:
        return [f for f in self._faults if f.kind == kind and now >= self.t0 + f.at_s
                and (self.clock_started or f.at_s == 0)]

    # --- serving thread ---------------------------------------------------------------

    def _serve(self) -> None:
        """Answer requests as they come. On the wall clock the wrist also steps while idle; in
        simulated time nothing moves between requests, and a reply held back is written once
        the clock reaches it (polled while one is); the clock is told what was answered."""
        self.realtime = request_realtime(EMULATOR_PRIORITY)
        sim = self.sim
        idle = IDLE_S if self.wrist is None else PHYSICAL_IDLE_S
        try:
            while not self._stop.is_set():
                try:
                    ready, _, _ = select.select(self._endpoint.fds(), [], [], self._wait_s(idle))
                except (OSError, ValueError):
                    return
                received = self._endpoint.receive(ready) if ready else []
                with self._lock:
                    now = self._clock()
                    if sim is None or received:
                        self._advance(now)
                    for channel, data in received:
                        self._handle(channel, data, now)
                    if received and not self.clock_started and any(sv.torque for sv in self.servos):
                        self.start_clock()  # the first torque-on: the motion starts
                    self._flush(now)
                    if sim is not None:
                        sim.due = self._pending[0][0] if self._pending else math.inf
                        sim.answered(sum(len(data) for _, data in received))
        finally:
            self._stop.set()

    def _wait_s(self, idle: float) -> float:
        """How long the serving thread may sleep for new bytes (wall clock), s."""
        if self.sim is not None:
            return SIM_POLL_S if self._pending else IDLE_S
        if self._pending:
            return max(0.0, min(idle, self._pending[0][0] - time.perf_counter()))
        return idle

    def _handle(self, channel: Channel, data: bytes, now: float) -> None:
        decoder = channel.decoder
        if decoder.pending and now - channel.last_rx > GAP_S:
            self.stats.rejected_bytes += decoder.pending
            decoder.reset()
        channel.last_rx = now
        before = decoder.skipped
        packets = decoder.feed(data)
        self.stats.rejected_bytes += decoder.skipped - before
        for pkt in packets:
            self.stats.instructions += 1
            if self._active("unplug", now):
                self.stats.silenced += 1
                continue
            if isinstance(pkt, p2.Packet):
                replies = dispatch2(self._by_id, pkt)
            elif isinstance(pkt, p1.Packet):
                replies = dispatch1(self._by_id, pkt)
            else:  # neither protocol's packet: no decoder makes one
                continue
            if replies and self._record and self._t and pkt.instruction in _READS:
                self._reads.append(len(self._t) - 1)  # the record _advance(now) just took
            for _ident, raw in replies:
                self._emit(channel, raw, now)
            if any(k != sv.id for k, sv in self._by_id.items()):  # an ID written
                self._by_id = {sv.id: sv for sv in self.servos}

    def _emit(self, channel: Channel, raw: bytes, now: float) -> None:
        for f in self._active("drop", now):
            if self._frng.random() < (f.rate or 0.0):
                self.stats.dropped += 1
                return
        for f in self._active("corrupt", now):
            if self._frng.random() < (f.rate or 0.0):
                self.stats.corrupted += 1
                raw = raw[:-1] + bytes(((raw[-1] ^ 0x5A) & 0xFF,))
                break
        delay = sum(f.delay_s or 0.0 for f in self._active("delay", now))
        if delay > 0:
            self.stats.delayed += 1
        due = now + delay
        if self._pending:
            due = max(due, self._pending[-1][0])
        self._pending.append((due, channel, raw))
        self.stats.replies += 1

    def _flush(self, now: float) -> None:
        while self._pending and self._pending[0][0] <= now:
            _, channel, raw = self._pending.pop(0)
            channel.write(raw)


def _physical_wrist(profile: Profile, theta0_deg: Sequence[float],
                    truth: TrueWrist | None = None) -> PhysicalWrist | None:
    """The physical wrist (the profile's, or ``truth``'s) at rest at θ0 (deg) (its clock set by
    the caller); None for ideal servos."""
    if profile.plant.model != "physical":
        return None
    from spm_console.devices.emulator.physical import PhysicalWrist  # loads MuJoCo

    model = model_of(profile) if truth is None else truth.model
    wrist = PhysicalWrist(model, plant_params(profile.plant), profile.bus.ticks_per_turn,
                          link_model_of(profile), None if truth is None else truth.body)
    wrist.set_theta(np.radians(np.asarray(theta0_deg, float)))
    return wrist


def start_emulator(profile: Profile, faults: Sequence[FaultSpec] = (), record: bool = True,
                   initial_deg: Sequence[float] | None = None,
                   link: Link | None = None, *, truth: TrueWrist | None = None,
                   jig: bool = False, truth_log: TruthLog | None = None,
                   sim: SimClock | None = None) -> EmulatorHandle:
    """Start an emulated bus for ``profile`` in a background thread; open ``handle.port``
    (``link``: a Unix-domain socket, ``unix:PATH``, or a pseudo-terminal; default the
    profile's ``emulator.link``).

    The servos start at the profile's home θ (or ``initial_deg``), torque off, goal
    equal to their position. Fault times count from the clock start: the first torque-on
    (the first motion, whichever process drives it) or an earlier
    :meth:`EmulatorHandle.start_clock`; until then only faults at t = 0 act.

    With ``truth`` (:func:`~spm_console.devices.emulator.twin.true_wrist`) the bus serves that
    wrist as built; on the physical plant, ``jig`` powers it on held at the true home until the
    first torque-on, and ``truth_log`` (closed by ``stop()``) receives its truth at 100 Hz.
    ``sim``: serve in simulated time (the module docstring).
    """
    return EmulatorHandle(profile, faults, record, initial_deg, link, truth=truth, jig=jig,
                          truth_log=truth_log, sim=sim)
