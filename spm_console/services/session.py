"""One operator session: the state behind the console and its blocking operations.

No Textual here: the TUI calls these methods from worker threads and the
headless script runner (:mod:`spm_console.scripting.runner`) calls them directly, so both
drive the same core, bus, executor and safety checks. Every method raises
:class:`~spm_console.errors.SpmError` subclasses for operator errors. Angles in
degrees, time in seconds, lengths in mm.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from spm_console.config.schema import Profile
from spm_console.core.plan import Plan
from spm_console.devices.base import ServoStatus
from spm_console.devices.emulator.bus import EmulatorHandle, start_emulator
from spm_console.devices.emulator.child import EmulatorChild
from spm_console.devices.emulator.faults import FaultSpec
from spm_console.errors import (
    BadInputError,
    BusError,
    Issue,
    SpmError,
)
from spm_console.motion.plan_check import PlanCheck
from spm_console.motion.protocol import Planned
from spm_console.motion.sample import Sample
from spm_console.motion.segments import ExecutionResult
from spm_console.services.plan_store import PlanStore
from spm_console.services.session_follow import FollowTools
from spm_console.services.session_tools import ServoTools
from spm_console.services.warm_start import fork_helper
from spm_console.services.wrist_events import log_wrist_events, start_window
from spm_console.services.wrist_service import PoseSpec, WristService
from spm_console.system.cpus import cpu_plan, place_beside_loop
from spm_console.system.env import clock_override
from spm_console.system.simclock import SimClock

if TYPE_CHECKING:
    from spm_console.motion.homing import HomingResult
    from spm_console.services.client import MotionClient

F = NDArray[np.float64]

SampleCallback = Callable[["Sample"], None]


@dataclass
class BusState:
    """What the connect step found."""

    port: str
    emulated: bool
    statuses: list[ServoStatus] = field(default_factory=list)
    emulator_realtime: str = ""
    """The emulated servos' scheduling ("" on a real bus)."""
    emulator_realtime_granted: bool = True
    cpu_placement: str = ""
    """Where the servo loop and the console run (see :mod:`spm_console.system.cpus`)."""


def _clock_default(profile: Profile) -> tuple[bool, float]:
    """Whether an emulated bus runs in simulated time unless told, and at what pace (0: as
    fast as computed): ``SPM_CONSOLE_CLOCK``, else the profile's ``[emulator]`` clock."""
    try:
        override = clock_override()
    except ValueError as exc:
        raise BadInputError(str(exc)) from None
    if override is not None:
        return override[0] == "simulated", override[1]
    return profile.emulator.clock == "simulated", profile.emulator.clock_rate


class Session:
    """One operator session on the bus (thread-safe enough: one motion at a time, E-stop from
    any thread): connect, home, execute a plan it is given, E-stop. Its parts: ``wrist``
    (:class:`~spm_console.services.wrist_service.WristService`: FK, IK, the workspace),
    ``plans`` (:class:`~spm_console.services.plan_store.PlanStore`: the current plan),
    ``tools`` (:class:`~spm_console.services.session_tools.ServoTools`: health, torque,
    reboot, jog) and ``following``
    (:class:`~spm_console.services.session_follow.FollowTools`); the last two run their
    motions through :meth:`run_motion`."""

    def __init__(
        self,
        profile: Profile,
        port: str | None = None,
        sim: bool = True,
        logs_root: Path | None = None,
        cache_dir: Path | None = None,
        faults: Sequence[FaultSpec] = (),
        initial_deg: Sequence[float] | None = None,
        emulator_process: bool = False,
        sim_time: bool | None = None,
        preview: bool = False,
    ) -> None:
        self.profile = profile
        self.wrist = WristService(profile, cache_dir)
        """FK, IK and the workspace (no bus)."""
        self.plans = PlanStore(self.wrist)
        """The current plan (solved or opened), passed to :meth:`execute` as an argument."""
        self.port = port or (None if sim else (profile.bus.port or None))
        if not sim and not self.port:
            raise BadInputError("no serial port: give --port DEV, set bus.port in the profile, "
                                "or use --sim for the emulated bus")
        self.sim = self.port is None
        self.logs_root = logs_root
        self.cache_dir = cache_dir
        self.faults = tuple(faults)
        self.initial_deg = initial_deg
        simulated, self.sim_rate = _clock_default(profile)
        if preview:  # a preview is wanted now: as fast as computed, whatever paces the rest
            self.sim_rate = 0.0
        self.sim_time = self.sim and (simulated if sim_time is None else sim_time)
        """The emulated bus runs in simulated time (:mod:`spm_console.system.simclock`; default
        ``SPM_CONSOLE_CLOCK``, else the profile's ``[emulator] clock``), at ``sim_rate``
        simulated seconds per wall-clock second (0: as fast as computed)."""
        self.sim_clock: SimClock | None = None
        """The simulated clock while connected in simulated time."""
        self.preview = preview
        """The session previews a run on the wrist's twin (its run logs say so)."""
        self.emulator_process = emulator_process
        """Run the emulated bus in a child process (the console: its UI thread must not
        delay the emulator's replies) rather than in a thread of this process."""
        self.bus: MotionClient | None = None
        """The motion process (it owns the port); None when not connected."""
        self.bus_state: BusState | None = None
        self.tools = ServoTools(self)
        """Servo health, torque per joint, reboot, one-joint jog."""
        self.following = FollowTools(self)
        """Live and timed following."""
        self.emulator: EmulatorHandle | EmulatorChild | None = None
        self.theta_deg: F | None = None
        """Last measured motor angles, deg (None before connecting)."""
        self.homing: HomingResult | None = None
        """The last homing run (start pose, FK seed at the end)."""
        self.before_motion: Callable[[], None] | None = None
        """Called once a motion is marked as running, before it is sent (a signal that came
        earlier refuses it here; one that comes later finds the motion and stops it)."""
        self.last_run: ExecutionResult | None = None
        self.motion_total_s = 0.0
        """Planned duration of the running (or last) motion, s."""
        self._estop_sent = False
        self._motion = threading.Lock()
        self.moving = threading.Event()
        """Set while a motion (homing or execution) runs."""

    # ------------------------------------------------------------------ bus
    def clock(self) -> float:
        """Now on the motion's clock: ``time.perf_counter()``, or the simulated time."""
        return time.perf_counter() if self.sim_clock is None else self.sim_clock.now()

    @property
    def homed(self) -> bool:
        """Whether the motion process has the wrist homed (its own flag, from its latest
        answer); False when not connected."""
        return self.bus is not None and self.bus.homed

    @property
    def bus_label(self) -> str:
        """Where motions go, as the front ends word it (the emulated wrist named when it is
        the physical one)."""
        if not self.sim:
            return f"serial port {self.port}"
        return "emulated bus" if self.profile.plant.model == "ideal" else "emulated bus (physical wrist)"

    def connect(self, check: bool = True) -> BusState:
        """Start the motion process on the bus (the emulator first in sim mode): it owns the
        port and runs every motion; then ping the servos (with their health) and read θ —
        unless ``check`` is False (bus diagnostics: a silent servo is what they report)."""
        self.disconnect()
        port = self.port
        cpu_plan()  # the CPU set is fixed before any child starts (see spm_console.system.cpus)
        # the emulated servos in a process of their own for a front end (its UI thread would
        # delay their replies past the bus's timeout) and for the physical wrist (its physics
        # would hold this interpreter's lock). A preview's twin serves in a thread here: in
        # simulated time no reply can be late (the clock waits for it), nothing acts on the
        # wrist while it runs, and a process would take longer to start than the whole run
        if self.sim_time:
            self.sim_clock = SimClock.create(rate=self.sim_rate)
        sim = self.sim_clock
        own_process = self.emulator_process or self.profile.plant.model == "physical"
        if self.sim and own_process and not (self.preview and sim is not None):
            # forked by the warm start the motion process comes from (its imports are done)
            child = EmulatorChild(self.profile, self.faults, self.initial_deg, sim,
                                  fork=fork_helper)
            self.emulator = child
            try:
                port = child.launch()
            except SpmError as exc:
                self.disconnect()
                raise BusError(exc.message) from None
        elif self.sim:
            self.emulator = start_emulator(self.profile, self.faults, record=False,
                                           initial_deg=self.initial_deg, sim=sim)
            port = self.emulator.port
        assert port is not None
        try:
            from spm_console.services.client import MotionClient

            client = MotionClient(self.profile, port, cache_dir=self.cache_dir,
                                  logs_root=None if self.logs_root is None else str(self.logs_root),
                                  sim=self.sim, faults=[str(f) for f in self.faults],
                                  sim_clock=sim, preview=self.preview)
            self.bus = client
            client.on_planned = self._planned
            placed = place_beside_loop()  # the loop's children started: off their CPU
            rt, granted = self._emulator_realtime()
            self.bus_state = BusState(port=port, emulated=self.sim,
                                      statuses=client.ping_all() if check else [],
                                      emulator_realtime=rt, emulator_realtime_granted=granted,
                                      cpu_placement=placed)
            if check:
                self.read_position()
        except SpmError:
            self.disconnect()
            raise
        except OSError as exc:
            self.disconnect()
            raise BusError(f"{port}: {exc.strerror or exc}") from None
        return self.bus_state

    def _emulator_realtime(self) -> tuple[str, bool]:
        """The emulated servos' scheduling: (detail, SCHED_FIFO granted); ("", True) on a
        real bus."""

        emu = self.emulator
        if emu is None:
            return "", True
        if isinstance(emu, EmulatorHandle):
            return emu.realtime.detail, emu.realtime.policy == "SCHED_FIFO"
        return emu.realtime, emu.realtime_granted

    def require_bus(self) -> MotionClient:
        if self.bus is None:
            raise BusError("not connected to the servos: connect first", Issue.NOT_CONNECTED)
        return self.bus

    def read_position(self) -> F:
        self.theta_deg = np.asarray(self.require_bus().read_position(), float)
        return self.theta_deg

    def disconnect(self) -> None:
        bus, self.bus = self.bus, None
        if bus is not None:
            with contextlib.suppress(OSError, SpmError):
                bus.close()
        emu, self.emulator = self.emulator, None
        if emu is not None:
            emu.stop()
        clock, self.sim_clock = self.sim_clock, None
        if clock is not None:
            clock.close()
        self.bus_state = None
        self.tools.health = None

    # ------------------------------------------------------------------ motion
    def run_motion(self, fn: Callable[[], ExecutionResult]) -> ExecutionResult:
        if not self._motion.acquire(blocking=False):
            raise BadInputError("a motion is already running")
        self._estop_sent = False
        self.moving.set()
        # a preview's peak current is over the run: its window starts here
        window = self.preview and start_window(self.emulator)
        began = self.clock()
        try:
            if self.before_motion is not None:
                self.before_motion()
            result = fn()
        finally:
            self.moving.clear()
            self._motion.release()
        log_wrist_events(self.emulator, self.profile, result.log_dir, began, self.clock(), window)
        if result.final_deg is not None and np.all(np.isfinite(result.final_deg)):
            self.theta_deg = np.asarray(result.final_deg, float)
        else:  # the last cycle had no reply: ask again rather than show a stale or NaN pose
            with contextlib.suppress(SpmError):
                self.read_position()
        self.last_run = result
        return result

    def home(self, on_sample: SampleCallback | None = None) -> ExecutionResult:
        """Move home at the profile's homing speed, in the motion process (which checks the
        assembly mode first and logs a refusal); ``self.homing`` keeps the whole result."""

        client = self.require_bus()
        self.motion_total_s = float("nan")  # until the runtime says how long its move is

        def run() -> ExecutionResult:
            self.homing = client.home(on_sample)
            return self.homing.execution

        return self.run_motion(run)

    def execute(self, plan: Plan, on_sample: SampleCallback | None = None,
                skip_homing: str = "", source: str | None = None,
                approach: bool = True) -> ExecutionResult:
        """Execute ``plan``, with a straight approach move to its start if needed, in the
        motion process, which verifies it against this profile's workspace first and says how
        long the whole run is (:attr:`motion_total_s`, from its
        :class:`~spm_console.motion.protocol.Planned`).

        The motion process refuses it (:class:`~spm_console.errors.RefusedError`) unless it
        homed the wrist, or ``skip_homing`` gives the operator's reason to override that
        (written to the run log). ``source``: where the plan came from (its file, for the run
        log). ``approach`` False: no approach move, the wrist must already be at the plan's
        start (else refused, nothing moved). The plan store hears how it ended
        (:meth:`PlanStore.ran`)."""
        client = self.require_bus()
        self.motion_total_s = plan.duration_s  # the approach is the runtime's: it says later
        tol = self.profile.safety.approach_tolerance_deg
        result = self.run_motion(lambda: client.execute(plan, on_sample, tol, skip_homing, source,
                                                        approach))
        self.plans.ran(plan, result.ok)
        return result

    def _planned(self, planned: Planned) -> None:
        """The runtime's word on the motion it is about to run (the reading thread)."""
        self.motion_total_s = planned.duration_s

    def verify(self, plan: Plan, log_kind: str = "") -> PlanCheck:
        """``plan`` verified by the motion process exactly as :meth:`execute` will verify it,
        moving nothing: before homing for a plan this session did not solve (refused with
        :class:`~spm_console.errors.PlanRefusedError`, exit 26, saying nothing moved;
        ``log_kind``: the runtime also leaves a run folder of that kind for the refusal)."""
        return self.require_bus().verify(plan, log_kind)

    def estop(self, reason: str = "operator E-stop", by_signal: bool = False) -> bool:
        """Stop the running motion at once (any thread, a signal handler); False when nothing
        moves. Asked before the motion process started it, it is kept for it there.
        ``by_signal``: a terminating signal asked (before the first reference, the run is an
        interruption, exit 130)."""
        if not self.moving.is_set() or self.bus is None:
            return False
        if not self._estop_sent:  # the first reason is the one logged
            self._estop_sent = True
            self.bus.estop(reason, by_signal)
        return True

    def resolve(self, spec: PoseSpec) -> F:
        """Motor angles (deg) of a pose given as θ, as an orientation, as home or 'current'
        (the θ last measured on this session's bus)."""
        return self.wrist.resolve(spec, self.theta_deg)

    def close(self, wait_s: float = 3.0) -> None:
        """E-stop any motion, let the executor finish its stop and log, then disconnect."""
        if self.estop("console closing"):
            t_end = time.monotonic() + wait_s
            while self.moving.is_set() and time.monotonic() < t_end:
                time.sleep(0.01)
        self.disconnect()
