"""A Bosch BNO055 in UART mode on a serial port: a USB-UART adapter or the emulator's pty.

:meth:`Bno055.open` opens the port (115200 baud, 8N1, exclusive), reads CHIP_ID and refuses
anything that is not a BNO055 (:class:`~spm_console.errors.ImuError`, exit 10, naming what it
read, or that nothing answered); then it reads UNIT_SEL and OPR_MODE, so samples are converted
with the units the chip is set to. :meth:`Bno055.set_mode` switches the operating mode through
CONFIGMODE and waits the datasheet's switching time (Bosch BST-BNO055-DS000 Table 3-6);
:meth:`Bno055.read_sample` reads the whole data block 0x08..0x33 in one frame (one instant:
burst reads are shadowed, §3.7).

Every wait is bounded: a reply must be complete within ``timeout_s`` of its request (50 ms by
default; the longest reply, 46 bytes, takes 4 ms at 115200 baud), and a request is tried at
most ``attempts`` times (3), the line drained between tries until it has been quiet for
:data:`RETRY_QUIET_S`. Retried: no reply, bytes that are no reply, and the statuses a busy
chip sends (READ_FAIL, WRITE_FAIL, BUS_OVER_RUN, RECEIVE_CHARACTER_TIMEOUT,
WRONG_START_BYTE). The other statuses say the request itself is wrong: an ImuError at once.
"""

from __future__ import annotations

import contextlib
import select
import time
from dataclasses import dataclass

import serial

from spm_console.devices.imu import bno055_protocol as bp
from spm_console.devices.imu import bno055_registers as br
from spm_console.devices.imu.bno055_protocol import Quat, Status, Vec3
from spm_console.devices.imu.bno055_registers import OprMode, Reg
from spm_console.errors import BadInputError, ImuError

BAUD = 115_200
DEFAULT_TIMEOUT_S = 0.05
DEFAULT_ATTEMPTS = 3
TIMEOUT_RANGE_S = (0.005, 1.0)
"""Allowed ``timeout_s``, s."""
MAX_ATTEMPTS = 10
RETRY_QUIET_S = 0.03
"""Quiet line before a retry, s: late replies are let in and dropped, and a chip that
discards a garbled frame until the line is idle listens again."""
RETRY_MAX_S = 0.2
"""Longest drain before a retry, s (a line that never goes quiet)."""
SWITCH_MARGIN_S = 0.002
"""Added to Table 3-6's switching time before OPR_MODE is read back, s."""
_BUSY = frozenset((Status.READ_FAIL, Status.WRITE_FAIL, Status.BUS_OVER_RUN,
                   Status.RECEIVE_CHARACTER_TIMEOUT, Status.WRONG_START_BYTE))


@dataclass(frozen=True)
class ImuSample:
    """One reading of the data block, in the sensor's (remapped) axes; None for what the
    operating mode does not output (a sensor it leaves off, the fusion outside fusion modes)."""

    t_s: float
    """``time.monotonic()`` when the reply was complete, s."""
    mode: OprMode
    accel_mps2: Vec3 | None
    """Acceleration (specific force: +9.81 m/s² up at rest), m/s²."""
    gyro_dps: Vec3 | None
    """Angular rate, °/s."""
    mag_ut: Vec3 | None
    """Magnetic field, µT."""
    quat_wxyz: Quat | None
    """Fused orientation, unit quaternion w, x, y, z."""
    euler_deg: Vec3 | None
    """Fused orientation as EUL_DATA holds it: heading, roll, pitch, deg (the chip's conventions,
    Table 3-13; prefer the quaternion)."""
    gravity_mps2: Vec3 | None
    """Gravity as the fusion sees it (+9.81 m/s² up), m/s²."""
    linear_accel_mps2: Vec3 | None
    """Acceleration less gravity, m/s²."""


class _NoReplyError(Exception):
    """No complete reply within the timeout."""


class _GarbageError(Exception):
    """Bytes that are no reply."""

    def __init__(self, data: bytes) -> None:
        super().__init__(data.hex(" "))
        self.data = data


class _UnansweredError(Exception):
    """Every try of one request failed; what was seen."""

    def __init__(self, silent: int, garbage: bytes, statuses: list[Status]) -> None:
        super().__init__("unanswered")
        self.silent = silent
        self.garbage = garbage
        self.statuses = statuses


class Bno055:
    """An open BNO055 (use :meth:`open`). Not thread-safe: one caller at a time."""

    def __init__(self, ser: serial.Serial, port: str, timeout_s: float, attempts: int) -> None:
        self._ser = ser
        self.port = port
        self.timeout_s = timeout_s
        self.attempts = attempts
        self.mode = OprMode.CONFIG
        """The operating mode, as last read or set."""
        self.units = br.Units.of(0)
        """The units UNIT_SEL selects (read at open)."""

    @classmethod
    def open(cls, port: str, *, timeout_s: float = DEFAULT_TIMEOUT_S,
             attempts: int = DEFAULT_ATTEMPTS) -> Bno055:
        """Open ``port`` and check that a BNO055 answers on it (ImuError otherwise)."""
        lo, hi = TIMEOUT_RANGE_S
        if not lo <= timeout_s <= hi:
            raise BadInputError(f"IMU reply timeout {timeout_s} s: allowed {lo}..{hi} s")
        if not 1 <= attempts <= MAX_ATTEMPTS:
            raise BadInputError(f"IMU attempts {attempts}: allowed 1..{MAX_ATTEMPTS}")
        if not port:
            raise BadInputError("no serial port given for the IMU")
        try:
            ser = serial.Serial(port=port, baudrate=BAUD, bytesize=serial.EIGHTBITS,
                                parity=serial.PARITY_NONE, stopbits=serial.STOPBITS_ONE,
                                timeout=0, write_timeout=0.5, exclusive=True)
        except (serial.SerialException, OSError, ValueError) as exc:
            raise ImuError(f"cannot open the IMU's serial port {port}: {exc}. Check the device "
                           "path, that the adapter is plugged in and that you may use it (the "
                           "'dialout' group)") from None
        imu = cls(ser, port, timeout_s, attempts)
        try:
            imu._identify()
        except BaseException:
            imu.close()
            raise
        return imu

    def _identify(self) -> None:
        try:
            chip_id = self._request(bp.read_frame(Reg.CHIP_ID, 1), 1)[0]
        except _UnansweredError as u:
            if u.garbage:
                head = u.garbage[0]
                why = ("a read reply of the wrong length (a BNO055 answers CHIP_ID with "
                       "BB 01 and one byte)" if head == 0xBB else
                       "a status that is no answer to a read" if head == 0xEE else
                       "no BNO055 reply (a BNO055 replies 0xBB or 0xEE)")
                raise ImuError(f"not a BNO055 on {self.port}: it answered "
                               f"{u.garbage[:8].hex(' ')}: {why}") from None
            if u.statuses:
                raise ImuError(f"the IMU on {self.port} failed every read of CHIP_ID "
                               f"({self.attempts} tries): {_statuses(u.statuses)}") from None
            raise ImuError(f"no reply from an IMU on {self.port} within "
                           f"{self.timeout_s * 1e3:.0f} ms ({self.attempts} tries): check its power "
                           "and wiring (TX to RX), that PS1 is high (UART mode) and the port (the "
                           "IMU's, not the servo bus's: the two may be swapped)") from None
        if chip_id != br.CHIP_ID_VALUE:
            raise ImuError(f"not a BNO055 on {self.port}: CHIP_ID 0x{chip_id:02X} "
                           f"(a BNO055 reads 0x{br.CHIP_ID_VALUE:02X})")
        unit_sel, _, opr = self.read(Reg.UNIT_SEL, 3)
        self.units = br.Units.of(unit_sel)
        self.mode = OprMode(opr & 0x0F) if opr & 0x0F <= OprMode.NDOF else OprMode.CONFIG

    # --- registers ----------------------------------------------------------------------

    def read(self, reg: int, length: int) -> bytes:
        """``length`` bytes of page 0 from ``reg`` (1..128 bytes within 0x00..0x7F)."""
        _within_page(reg, length)
        frame = bp.read_frame(reg, length)
        return self._checked(frame, length, f"read {length} bytes at 0x{reg:02X}")

    def write(self, reg: int, data: bytes) -> None:
        """Write ``data`` to page 0 from ``reg``; ImuError when the chip refuses."""
        data = bytes(data)
        _within_page(reg, len(data))
        frame = bp.write_frame(reg, data)
        self._checked(frame, 0, f"write {len(data)} bytes at 0x{reg:02X}")

    def set_mode(self, mode: OprMode | int) -> None:
        """Switch to ``mode`` (through CONFIGMODE from another operating mode), wait the switch
        time and read OPR_MODE back. ImuError when the chip does not take it."""
        try:
            target = OprMode(int(mode))
        except ValueError:
            raise BadInputError(f"no BNO055 operating mode 0x{int(mode):02X}") from None
        if target == self.mode:
            return
        if self.mode != OprMode.CONFIG and target != OprMode.CONFIG:
            self._switch(OprMode.CONFIG)
        self._switch(target)

    def _switch(self, mode: OprMode) -> None:
        before = self.mode
        self.write(Reg.OPR_MODE, bytes((int(mode),)))
        time.sleep(br.switch_time_s(before, mode) + SWITCH_MARGIN_S)
        got = self.read(Reg.OPR_MODE, 1)[0] & 0x0F
        if got != mode:
            raise ImuError(f"the IMU on {self.port} did not enter {mode.name}: OPR_MODE reads "
                           f"0x{got:02X}")
        self.mode = mode

    def read_sample(self) -> ImuSample:
        """The data block in one burst read (ImuError in CONFIGMODE, which outputs nothing)."""
        if self.mode == OprMode.CONFIG:
            raise ImuError(f"the IMU on {self.port} is in CONFIGMODE, which outputs no data: "
                           "set an operating mode first")
        block = self.read(br.DATA_START, br.DATA_LEN)
        t = time.monotonic()
        d = bp.decode_data(block, self.units)
        info = br.MODES[self.mode]
        fused = info.fusion != "none"
        return ImuSample(
            t_s=t, mode=self.mode,
            accel_mps2=d.accel_mps2 if info.acc else None,
            gyro_dps=d.gyro_dps if info.gyr else None,
            mag_ut=d.mag_ut if info.mag else None,
            quat_wxyz=d.quat_wxyz if fused else None,
            euler_deg=d.euler_deg if fused else None,
            gravity_mps2=d.gravity_mps2 if fused else None,
            linear_accel_mps2=d.linear_accel_mps2 if fused else None)

    def close(self) -> None:
        with contextlib.suppress(serial.SerialException, OSError):
            self._ser.close()

    def __enter__(self) -> Bno055:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- transactions -------------------------------------------------------------------

    def _checked(self, frame: bytes, length: int, what: str) -> bytes:
        try:
            return self._request(frame, length)
        except _UnansweredError as u:
            seen = (_statuses(u.statuses) if u.statuses else
                    f"bytes that are no reply: {u.garbage[:8].hex(' ')}" if u.garbage else
                    f"no reply within {self.timeout_s * 1e3:.0f} ms")
            raise ImuError(f"the IMU on {self.port} did not {what} in {self.attempts} tries "
                           f"({seen})") from None

    def _request(self, frame: bytes, length: int) -> bytes:
        """Send ``frame`` until it is answered: the data of a read of ``length`` bytes, or b""
        for a write's WRITE_SUCCESS. _UnansweredError after every try failed; ImuError for a status
        that no retry can change."""
        silent, garbage, statuses = 0, b"", list[Status]()
        for k in range(self.attempts):
            if k:
                self._drain()
            try:
                raw = self._transact(frame)
            except _NoReplyError:
                silent += 1
                continue
            except _GarbageError as exc:
                garbage = garbage or exc.data
                continue
            reply = bp.decode_reply(raw)
            if reply.status is None and length and len(reply.data) == length:
                return reply.data
            if reply.status == Status.WRITE_SUCCESS and not length:
                return b""
            if reply.status is None or reply.status == Status.WRITE_SUCCESS:
                garbage = garbage or raw  # the wrong kind of reply, or the wrong length
                continue
            if reply.status not in _BUSY:
                raise ImuError(f"the IMU on {self.port} refused the request "
                               f"{frame[:4].hex(' ')}: {_statuses([reply.status])}")
            statuses.append(reply.status)
        raise _UnansweredError(silent, garbage, statuses)

    def _transact(self, frame: bytes) -> bytes:
        """One try: the reply's bytes. _NoReplyError when it is not complete within ``timeout_s``;
        _GarbageError for bytes that are no reply."""
        try:
            self._ser.reset_input_buffer()
            self._ser.write(frame)
            fd = self._ser.fileno()
            deadline = time.monotonic() + self.timeout_s
            buf = bytearray()
            while True:
                try:
                    size = bp.reply_size(bytes(buf[:2]))
                except bp.FrameError:
                    raise _GarbageError(bytes(buf) + self._ser.read(16)) from None
                if size is not None and len(buf) >= size:
                    return bytes(buf[:size])
                left = deadline - time.monotonic()
                if left <= 0:
                    raise _NoReplyError
                ready, _, _ = select.select([fd], [], [], left)
                if ready:
                    buf += self._ser.read(max(1, min(self._ser.in_waiting, 2 + bp.MAX_LEN)))
        except (serial.SerialException, OSError) as exc:
            raise ImuError(f"the IMU's serial port {self.port} failed: {exc}") from None

    def _drain(self) -> None:
        """Read and drop input until the line has been quiet for RETRY_QUIET_S (at most
        RETRY_MAX_S)."""
        try:
            fd = self._ser.fileno()
            end = time.monotonic() + RETRY_MAX_S
            while (left := end - time.monotonic()) > 0:
                ready, _, _ = select.select([fd], [], [], min(RETRY_QUIET_S, left))
                if not ready:
                    return
                self._ser.read(max(1, self._ser.in_waiting))
        except (serial.SerialException, OSError) as exc:
            raise ImuError(f"the IMU's serial port {self.port} failed: {exc}") from None


def _within_page(reg: int, length: int) -> None:
    if not 0 <= reg < br.PAGE_SIZE or not 1 <= length <= bp.MAX_LEN or reg + length > br.PAGE_SIZE:
        raise BadInputError(f"BNO055 request of {length} bytes at 0x{reg:02X}: page 0 holds "
                            f"0x00..0x7F, 1..{bp.MAX_LEN} bytes a frame")


def _statuses(statuses: list[Status]) -> str:
    names = dict.fromkeys(f"0x{int(s):02X} {s.name}" for s in statuses)
    return "status " + ", ".join(names)
