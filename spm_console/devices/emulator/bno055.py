"""An emulated Bosch BNO055 in UART mode on a pseudo-terminal (Bosch BST-BNO055-DS000 rev 1.4).

:class:`EmulatedBno055` serves one chip on a raw pty pair (``devices/emulator/endpoint.py``):
``port`` is the slave's path, which the driver (or any serial tool) opens at 115200 baud. A
thread answers the frames (``devices/emulator/bno055_uart.py``); :class:`Bno055Chip` is the
register file and the sensors, usable without a pty (tests give it their own clock).

What the chip does (datasheet section, or our choice where it says nothing):

- Page 0 with the reset values of §4.2 (``bno055_registers.REGISTERS``); page 1 is not emulated
  (PAGE_ID ≠ 0 → WRITE_FAIL). Read-only and reserved bytes refuse writes (WRITE_DISABLED), so do
  CONFIGMODE-only registers in another mode (§3.3.1); a refused write changes nothing.
- OPR_MODE: every mode of Table 3-5. A switch takes Table 3-6's time (7 ms out of CONFIGMODE,
  19 ms into it, both between two operating modes); meanwhile reads answer READ_FAIL and
  writes WRITE_FAIL. Writing the current mode again is no switch. In CONFIGMODE the data
  registers read 0 (§3.3.1: output reset to zero), as do those of sensors or fusion outputs
  the mode does not run.
- PWR_MODE: normal only (another value → WRITE_FAIL). SYS_TRIGGER bit 5 (RST_SYS) resets the
  register file; the chip then answers nothing for :data:`RESET_S` (the power-on time).
- UNIT_SEL: m/s² or mg, °/s or rad/s, degrees or radians, °C or °F, all honoured (§3.6.1);
  bit 7 (Windows/Android orientation) is stored and changes nothing.
- AXIS_MAP_CONFIG/SIGN applied to every vector output (§3.4); an invalid configuration keeps
  the previous one, as the datasheet says. A remap that mirrors (an odd number of negations
  or swaps) cannot turn a frame by a rotation: the fused orientation then stays in the chip's
  own axes.
- Data registers hold samples at the mode's output rate (Table 3-14; 100 Hz outside fusion):
  a read gets the newest, computed when first read (``truth()`` is called then, from the
  serving thread).

The sensor model: the truth (:class:`ImuTruth`) plus white noise of the datasheet's densities
(accelerometer 150 µg/√Hz, gyroscope 0.014 °/s/√Hz) over the default bandwidths of Table 3-4
(62.5 Hz, 32 Hz) taken as ideal: σ = density·√bandwidth per sample, 0.0116 m/s² and 0.079 °/s
(about one LSB each), independent from sample to sample; then range saturation (±4 g,
±2000 °/s) and quantisation to the LSB. No bias, drift or scale error. The magnetometer sees a
fixed field (:data:`MAG_WORLD_UT`) through the true orientation, without noise. The fusion:
the true orientation turned by a small random rotation (σ :data:`FUSION_SIGMA_DEG` per
axis); in relative modes (IMU, M4G) with the heading at the mode's first sample zeroed; gravity
(GRV) is that orientation's view of +g along world z (the accelerometer's sign: +9.81 m/s² up
at rest), LIA = ACC − GRV.
EUL_DATA: heading = −yaw (clockwise seen from above, 0..360°), roll = the Z-Y-X decomposition's
rotation about y (±90°), pitch = about x (±180°), the ranges of Table 3-13; the chip's own signs
are not emulated: use the quaternion (world ← sensor, w, x, y, z, w ≥ 0).
"""

from __future__ import annotations

import math
import select
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.rotations import expm_so3, matrix_quaternion, matrix_rpy, rpy_matrix
from spm_console.devices.emulator.bno055_uart import CHAR_TIMEOUT_S, Bno055Uart
from spm_console.devices.emulator.endpoint import Channel, PtyEndpoint
from spm_console.devices.imu import bno055_protocol as bp
from spm_console.devices.imu import bno055_registers as br
from spm_console.devices.imu.bno055_protocol import Status
from spm_console.devices.imu.bno055_registers import OprMode, Reg
from spm_console.system.realtime import HELPER_PRIORITY, RtGrant, request_realtime

F = NDArray[np.float64]

ACC_DENSITY_MPS2_RTHZ = 150e-6 * br.G_MPS2
"""Accelerometer noise density, m/s²/√Hz (150 µg/√Hz)."""
GYR_DENSITY_DPS_RTHZ = 0.014
"""Gyroscope noise density, °/s/√Hz."""
ACC_BANDWIDTH_HZ = 62.5
GYR_BANDWIDTH_HZ = 32.0
ACC_RANGE_MPS2 = 4.0 * br.G_MPS2
GYR_RANGE_DPS = 2000.0
FUSION_SIGMA_DEG = 0.05
"""Per-axis standard deviation of the fused orientation's error, deg (our choice)."""
MAG_WORLD_UT = (0.0, 20.0, -40.0)
"""The Earth's field in the world frame, µT (x east, y north, z up; mid-latitude, our choice)."""
RESET_S = 0.65
"""Time from RST_SYS to the first answer, s (the power-on-reset time)."""
IDLE_S = 0.02
"""Longest sleep of the serving thread with no frame in progress, s (stop() waits this long)."""


@dataclass(frozen=True)
class ImuTruth:
    """What the sensor is exposed to at ``t_s`` (the caller's clock, s).

    ``rotation``: 3x3, world ← sensor (a sensor-frame vector v is ``rotation @ v`` in the world;
    world z up). ``specific_force_mps2``: what an accelerometer reads, a − g in the sensor frame,
    m/s² (+9.81 along the up axis at rest). ``angular_rate_radps``: sensor frame, rad/s."""

    rotation: F
    specific_force_mps2: F
    angular_rate_radps: F
    t_s: float = 0.0

    def __post_init__(self) -> None:
        R = np.array(self.rotation, float)
        f = np.array(self.specific_force_mps2, float)
        w = np.array(self.angular_rate_radps, float)
        if R.shape != (3, 3) or f.shape != (3,) or w.shape != (3,):
            raise ValueError("ImuTruth: rotation is 3x3, specific force and rate are 3-vectors")
        if not (np.isfinite(R).all() and np.isfinite(f).all() and np.isfinite(w).all()):
            raise ValueError("ImuTruth: values must be finite")
        if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
            raise ValueError("ImuTruth: rotation is not a proper rotation matrix")
        for name, a in (("rotation", R), ("specific_force_mps2", f), ("angular_rate_radps", w)):
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @classmethod
    def at_rest(cls, rotation: F, t_s: float = 0.0) -> ImuTruth:
        """The sensor still at ``rotation`` (world ← sensor): it reads +g up, no rate."""
        R = np.asarray(rotation, float)
        return cls(R, R.T @ np.array([0.0, 0.0, br.G_MPS2]), np.zeros(3), t_s)

    @classmethod
    def at_rest_rpy(cls, roll_deg: float, pitch_deg: float, yaw_deg: float) -> ImuTruth:
        """:meth:`at_rest` at R = Rz(yaw)·Ry(pitch)·Rx(roll), deg."""
        return cls.at_rest(rpy_matrix(*np.radians([roll_deg, pitch_deg, yaw_deg])))


Truth = Callable[[], ImuTruth]


class Bno055Chip:
    """The register file and sensors of one BNO055 (module docstring); answers whole requests.

    ``clock()`` is seconds on any monotonic clock; ``seed`` seeds the noise (numpy Generator).
    Each sample draws a fixed number of values for its mode, so the n-th sample of a mode carries
    the same noise however the reads were timed; the same requests at the same clock readings
    get the same bytes. ``noise=False``: the truth, saturated and quantised only."""

    def __init__(self, truth: Truth, seed: int = 0, clock: Callable[[], float] = time.monotonic, *,
                 noise: bool = True, fusion_sigma_deg: float = FUSION_SIGMA_DEG,
                 mag_world_ut: tuple[float, float, float] = MAG_WORLD_UT,
                 temp_c: float = 25.0) -> None:
        self._truth = truth
        self._clock = clock
        self._rng = np.random.default_rng(seed)
        scale = 1.0 if noise else 0.0
        self.sigma_acc_mps2 = scale * ACC_DENSITY_MPS2_RTHZ * math.sqrt(ACC_BANDWIDTH_HZ)
        self.sigma_gyr_radps = scale * math.radians(GYR_DENSITY_DPS_RTHZ * math.sqrt(GYR_BANDWIDTH_HZ))
        self.sigma_fusion_rad = scale * math.radians(fusion_sigma_deg)
        self._mag_world = np.asarray(mag_world_ut, float)
        self.temp_c = temp_c
        self.page = br.reset_page()
        """Page 0's 128 bytes as a read would return them now."""
        self.mode = OprMode.CONFIG
        self._next: OprMode | None = None
        self._busy_until = -math.inf
        self._resetting = False
        self._t_mode = 0.0
        self._k = -1
        self._yaw0: float | None = None
        self.samples = 0
        """Samples drawn (truth() calls)."""

    # --- requests -----------------------------------------------------------------------

    def silent(self) -> bool:
        """Booting after RST_SYS: nothing is answered."""
        self._settle(self._clock())
        return self._resetting

    def read(self, reg: int, length: int) -> bytes | None:
        """The reply to a read of ``length`` bytes at ``reg`` (header already checked)."""
        now = self._clock()
        self._settle(now)
        if self._resetting:
            return None
        if now < self._busy_until:
            return bp.status_reply(Status.READ_FAIL)
        self._refresh(now)
        return bp.read_reply(bytes(self.page[reg:reg + length]))

    def write(self, reg: int, data: bytes) -> bytes | None:
        """The reply to a write of ``data`` at ``reg`` (header already checked)."""
        now = self._clock()
        self._settle(now)
        if self._resetting:
            return None
        if now < self._busy_until:
            return bp.status_reply(Status.WRITE_FAIL)
        status = self._refusal(reg, data)
        if status is not None:
            return bp.status_reply(status)
        for i, value in enumerate(data):
            self._store(reg + i, value, now)
        return bp.status_reply(Status.WRITE_SUCCESS)

    def _refusal(self, reg: int, data: bytes) -> Status | None:
        for i, value in enumerate(data):
            addr = reg + i
            r = br.register_at(addr)
            if r is None or r.access == br.Access.READ_ONLY:
                return Status.WRITE_DISABLED
            if r.access == br.Access.CONFIG and self.mode != OprMode.CONFIG:
                return Status.WRITE_DISABLED
            if ((addr == Reg.PAGE_ID and value != 0) or (addr == Reg.PWR_MODE and value != 0)
                    or (addr == Reg.OPR_MODE and value & 0x0F > OprMode.NDOF)):
                return Status.WRITE_FAIL
        return None

    def _store(self, addr: int, value: int, now: float) -> None:
        if addr == Reg.OPR_MODE:
            new = OprMode(value & 0x0F)
            if new != self.mode:
                self._busy_until = now + br.switch_time_s(self.mode, new)
                self._next = new
                self._clear_outputs()
        elif addr == Reg.SYS_TRIGGER:
            if value & 0x20:  # RST_SYS
                self.page = br.reset_page()
                self.mode, self._next = OprMode.CONFIG, None
                self._resetting = True
                self._busy_until = now + RESET_S
            else:  # self test, interrupt reset: nothing to do; CLK_SEL kept
                self.page[addr] = value & 0x80
        elif addr == Reg.AXIS_MAP_CONFIG:
            if br.axis_remap(value, self.page[Reg.AXIS_MAP_SIGN]) is not None:
                self.page[addr] = value
        else:
            self.page[addr] = value

    def _settle(self, now: float) -> None:
        """Finish a switch or a reset whose time is up."""
        if now < self._busy_until:
            return
        self._resetting = False
        if self._next is not None:
            self.mode, self._next = self._next, None
            self.page[Reg.OPR_MODE] = (self.page[Reg.OPR_MODE] & 0xF0) | int(self.mode)
            self._t_mode, self._k, self._yaw0 = self._busy_until, -1, None

    def _clear_outputs(self) -> None:
        self.page[br.DATA_START:Reg.CALIB_STAT + 1] = bytes(Reg.CALIB_STAT + 1 - br.DATA_START)
        self.page[Reg.SYS_STATUS] = 0

    # --- samples ------------------------------------------------------------------------

    def _refresh(self, now: float) -> None:
        info = br.MODES[self.mode]
        if self.mode == OprMode.CONFIG:
            return
        k = math.floor((now - self._t_mode) * info.rate_hz + 1e-6)  # due within 1 µs: sums of times round
        if k == self._k:
            return
        self._k = k
        units = br.Units.of(self.page[Reg.UNIT_SEL])
        self.page[br.DATA_START:Reg.TEMP] = bp.encode_data(self._sample(info), units)
        self.page[Reg.TEMP] = units.temp_raw(self.temp_c) & 0xFF
        fused = info.fusion != "none"
        self.page[Reg.CALIB_STAT] = ((0xC0 if fused else 0) | (0x30 if info.gyr else 0)
                                     | (0x0C if info.acc else 0) | (0x03 if info.mag else 0))
        self.page[Reg.SYS_STATUS] = 5 if fused else 6

    def _remap(self) -> F:
        P = br.axis_remap(self.page[Reg.AXIS_MAP_CONFIG], self.page[Reg.AXIS_MAP_SIGN])
        return np.eye(3) if P is None else np.asarray(P, float)

    def _sample(self, info: br.ModeInfo) -> bp.DataBlock:
        truth = self._truth()
        self.samples += 1
        R = truth.rotation
        P = self._remap()
        zero = (0.0, 0.0, 0.0)
        acc = gyr = mag = eul = lia = grv = zero
        quat = (0.0, 0.0, 0.0, 0.0)
        acc_out = np.zeros(3)
        if info.acc:
            f = truth.specific_force_mps2 + self._rng.normal(0.0, self.sigma_acc_mps2, 3)
            acc_out = P @ np.clip(f, -ACC_RANGE_MPS2, ACC_RANGE_MPS2)
            acc = _vec(acc_out)
        if info.gyr:
            w = np.degrees(truth.angular_rate_radps + self._rng.normal(0.0, self.sigma_gyr_radps, 3))
            gyr = _vec(P @ np.clip(w, -GYR_RANGE_DPS, GYR_RANGE_DPS))
        if info.mag:
            mag = _vec(P @ (R.T @ self._mag_world))
        if info.fusion != "none":
            proper = np.linalg.det(P) > 0
            frame = P.T if proper else np.eye(3)  # output axes in chip axes, when a rotation
            if self._yaw0 is None:
                ref = R @ frame
                self._yaw0 = (math.atan2(ref[1, 0], ref[0, 0]) if info.fusion == "relative"
                              else 0.0)
            c, s = math.cos(self._yaw0), math.sin(self._yaw0)
            unyaw = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # Rz(-yaw0)
            R_fused = unyaw @ R @ expm_so3(self._rng.normal(0.0, self.sigma_fusion_rad, 3))
            grv_out = P @ (R_fused.T @ np.array([0.0, 0.0, br.G_MPS2]))
            grv = _vec(grv_out)
            lia = _vec(acc_out - grv_out)
            R_out = R_fused @ frame
            x, y, z, w_ = (float(v) for v in matrix_quaternion(R_out))
            quat = (w_, x, y, z)
            roll_x, pitch_y, yaw_z = (math.degrees(float(v)) for v in matrix_rpy(R_out))
            heading = (-yaw_z) % 360.0
            if heading > 360.0 - 1.0 / 32.0:  # rounds to 360°, which the register holds as 0
                heading = 0.0
            eul = (heading, pitch_y, roll_x)
        return bp.DataBlock(acc, mag, gyr, eul, quat, lia, grv)


def _vec(v: F) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


class EmulatedBno055:
    """One emulated BNO055 on a raw pseudo-terminal: ``port`` is what a client opens;
    ``stop()`` (or leaving the ``with`` block) closes it. ``truth()`` is called from the serving
    thread when a sample is due; ``seed`` seeds the noise; the other keywords go to
    :class:`Bno055Chip`."""

    def __init__(self, truth: Truth, seed: int = 0, *, char_timeout_s: float = CHAR_TIMEOUT_S,
                 **chip: Any) -> None:
        self.chip = Bno055Chip(truth, seed, time.monotonic, **chip)
        self.uart = Bno055Uart(self.chip, time.monotonic, char_timeout_s)
        self._endpoint = PtyEndpoint(lambda: self.uart)
        self.port: str = self._endpoint.port
        """The pty slave's path (open it at 115200 baud, 8N1)."""
        self._channel: Channel | None = None
        self.error: Exception | None = None
        """What stopped the serving thread (an exception of ``truth()``), or None."""
        self.realtime = RtGrant("normal", "not serving yet")
        """The scheduling the serving thread got."""
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="spm-bno055", daemon=True)
        self._thread.start()

    def registers(self) -> bytes:
        """Page 0 as it stands (for tests; no sample is drawn)."""
        with self._lock:
            return bytes(self.chip.page)

    def stop(self) -> None:
        """Stop serving and close the pty."""
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        self._endpoint.close()

    def __enter__(self) -> EmulatedBno055:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def _serve(self) -> None:
        # truth() of the emulated wrist steps its physics under the emulated servos' lock: at
        # normal priority a busy machine could preempt this thread while it holds that lock,
        # and the servos' thread (SCHED_FIFO) would wait behind it and answer late
        self.realtime = request_realtime(HELPER_PRIORITY)
        while not self._stop.is_set():
            wait = IDLE_S
            due = self.uart.deadline()
            if due is not None:
                wait = min(wait, max(0.0, due - time.monotonic()))
            try:
                ready, _, _ = select.select(self._endpoint.fds(), [], [], wait)
            except (OSError, ValueError):
                return
            with self._lock:
                try:
                    self._answer(ready)
                except Exception as exc:  # a truth() that raised: kept for the test to see
                    self.error = exc
                    return

    def _answer(self, ready: list[int]) -> None:
        for ch, data in self._endpoint.receive(ready):
            self._channel = ch
            for reply in self.uart.feed(data):
                ch.write(reply)
        if self._channel is not None:
            for reply in self.uart.poll():
                self._channel.write(reply)
