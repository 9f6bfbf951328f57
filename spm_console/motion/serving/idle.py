"""The motion process's answers to the requests that move nothing (ping, read, servo status,
torque per joint, reboot, query, verify): :class:`IdleServer`, the base of its server, which
also holds the bus, the profile and its workspace. Degrees and seconds.
"""

from __future__ import annotations

import contextlib
import threading
from dataclasses import replace
from multiprocessing.connection import Connection

from spm_console.config.schema import Profile
from spm_console.core.workspace.data import Workspace
from spm_console.devices.base import CommError, ServoStatus, read_position_checked
from spm_console.devices.dynamixel.bus import open_bus
from spm_console.errors import PlanRefusedError, RefusedError, SpmError
from spm_console.motion import servo_tools
from spm_console.motion.plan_check import PlanCheck
from spm_console.motion.protocol import (
    Failed,
    Ping,
    Query,
    ReadPosition,
    Reboot,
    Reply,
    Status,
    Torque,
    Verify,
)
from spm_console.motion.runs import RunContext, refused_run, verify_before_motion
from spm_console.motion.servo_query import answer
from spm_console.store.workspace_cache import load_or_build
from spm_console.system.realtime import HELPER_PRIORITY, normal_priority, request_realtime


class IdleServer:
    """The child's bus, profile and workspace, and its answers while no motion runs."""

    def __init__(self, conn: Connection, profile: Profile, ctx: RunContext,
                 cache_dir: str | None) -> None:
        self.conn = conn
        self.profile = profile
        self.ctx = ctx
        self.cache_dir = cache_dir
        self._workspace: Workspace | None = None
        self.bus = open_bus(profile, ctx.port, sim=ctx.clock())
        self.send_lock = threading.Lock()
        self.homed = False
        """A homing run completed in this process (the rule: homed before any other motion)."""

    def send(self, msg: object) -> None:
        if isinstance(msg, (Reply, Failed)):  # every answer says whether the wrist is homed
            msg = replace(msg, homed=self.homed)
        with self.send_lock, contextlib.suppress(OSError, EOFError, BrokenPipeError):
            self.conn.send(msg)

    @staticmethod
    def refused(req_id: int, exc: SpmError) -> Failed:
        """The answer for an operator-facing error; a refusal keeps its reason code."""
        return Failed(req_id, exc.message, int(exc.exit_code),
                      str(exc.reason) if isinstance(exc, RefusedError) else "")

    # --- requests that move nothing ----------------------------------------------------
    def _answer(self, req: Ping | ReadPosition | Status | Torque | Reboot | Query | Verify) -> None:
        try:
            if isinstance(req, Verify):  # moves nothing: answered here, the loop is idle
                value: object = self.verify(req)
            elif isinstance(req, ReadPosition):
                value = read_position_checked(self.bus, 3)
            elif isinstance(req, Ping):
                value = self.ping()
            elif isinstance(req, Query):
                value = answer(self.bus, req.query)
            else:
                value = self.servo_tool(req)
            self.send(Reply(req.id, value))
        except SpmError as exc:
            self.send(self.refused(req.id, exc))
        except Exception as exc:  # a bug: say so, keep serving (no motion runs)
            self.send(Failed(req.id, f"internal error in the motion process: {exc!r}", 1))

    def verify(self, req: Verify) -> PlanCheck:
        """The plan verified as an execution will verify it. At normal priority: the workspace
        may be loaded or built first (seconds of CPU), which this real-time thread must not
        take from the emulated servos or the front end."""
        normal_priority()
        try:
            return verify_before_motion(self.profile, self.workspace, req.plan)
        except PlanRefusedError as exc:
            if req.log_kind:
                refused_run(self.profile, req.log_kind, self.ctx, exc)
            raise
        finally:
            request_realtime(HELPER_PRIORITY)

    def servo_tool(self, req: Status | Torque | Reboot) -> servo_tools.ServoHealth:
        """Torque per joint or a reboot (if asked), then every joint's health (ServoHealth).
        Torque off or a reboot (torque comes back off) un-homes the wrist: the joint can be
        moved by hand from then on."""
        if isinstance(req, (Torque, Reboot)):
            servo_tools.joint_index(self.bus, req.joint)  # a bad number changes nothing
            if isinstance(req, Reboot) or not req.on:
                self.homed = False
            if isinstance(req, Torque):
                servo_tools.set_joint_torque(self.bus, req.joint, req.on)
            else:
                servo_tools.reboot_joint(self.bus, req.joint, **self.ctx.timing())
        return servo_tools.read_health(self.bus)

    def ping(self) -> list[ServoStatus]:
        volt = "present_input_voltage" if self.profile.bus.protocol == "2.0" else "present_voltage"
        out = []
        for st in self.bus.ping_all():
            with contextlib.suppress(CommError, OSError, KeyError, SpmError):  # informative only
                st = replace(st, temperature_c=float(self.bus.read(st.id, "present_temperature")),
                             voltage_v=0.1 * float(self.bus.read(st.id, volt)))
            out.append(st)
        return out

    @property
    def workspace(self) -> Workspace:
        """This profile's workspace (cache, or built on first use): every motion is verified
        against it."""
        if self._workspace is None:
            self._workspace, _ = load_or_build(self.profile, cache_dir=self.cache_dir)
        return self._workspace
