"""An in-test fake ServoBus for the executor's pure logic (the integration tests use the
real emulator over a pty). It moves each joint by the continuous model (27) over real
elapsed time, exactly (matrix exponential), and quantizes reads to 4096 ticks."""

from __future__ import annotations

import threading
import time

import numpy as np
from scipy.linalg import expm

from spm_console.devices.base import CommError, ServoStatus

TICK = 360.0 / 4096


class SimClock:
    """A simulated clock: ``sleep`` advances it; nothing else does (deterministic timing)."""

    def __init__(self) -> None:
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t

    def sleep(self, dt: float) -> None:
        self.t += max(0.0, dt)


class FakeBus:
    def __init__(self, theta0_deg: np.ndarray, p: float = 32.22,
                 clock: SimClock | None = None, io_s: float = 0.0004,
                 timeout_s: float = 0.004) -> None:
        self.p = p
        self.clock = clock
        self.now = clock if clock is not None else time.perf_counter
        self.io_s = io_s
        self.timeout_s = timeout_s
        self.x = np.zeros((2, 3))
        self.x[0] = np.asarray(theta0_deg, float)
        self.goal = self.x[0].copy()
        self.torque = False
        self.t_last = self.now()
        self.lock = threading.Lock()
        self.t_start: float | None = None
        self.fail_reads_after: float | None = None  # every read fails from this time on
        self.fail_read_calls: set[int] = set()  # these read calls fail
        self.stall_joint: int | None = None
        self.stall_after = 0.0
        self.hw_error_after: float | None = None
        self.push_after: float | None = None  # external push of joint 1 by +push_deg
        self.push_deg = 0.0
        self.expose_alerts = False  # like DynamixelBus.alerts (status packets' alert bit)
        self.alerts: dict[int, int] = {}
        self.reads = 0
        self.writes: list[tuple[float, np.ndarray]] = []
        self.torque_calls: list[tuple[float, bool]] = []

    def _elapsed(self) -> float:
        return 0.0 if self.t_start is None else self.now() - self.t_start

    def start_clock(self) -> None:
        self.t_start = self.now()

    def _advance(self) -> None:
        now = self.now()
        dt, self.t_last = now - self.t_last, now
        if not self.torque or dt <= 0:
            return
        p = self.p
        Ac = np.array([[0, 1, 0], [-p * p, -2 * p, p * p], [0, 0, 0]], float)
        E = expm(Ac * dt)
        for i in range(3):
            if self.stall_joint == i and self._elapsed() >= self.stall_after:
                self.x[1, i] = 0.0
                continue
            s = E @ np.array([self.x[0, i], self.x[1, i], self.goal[i]])
            self.x[0, i], self.x[1, i] = s[0], s[1]
        if self.push_after is not None and self._elapsed() >= self.push_after:
            self.x[0, 0] += self.push_deg
            self.push_after = None

    # ServoBus ---------------------------------------------------------------
    def ping_all(self) -> list[ServoStatus]:
        return [ServoStatus(id=i + 1, model_number=321) for i in range(3)]

    def set_torque(self, on: bool) -> None:
        with self.lock:
            self._advance()
            self.torque = on
            self.torque_calls.append((self._elapsed(), on))

    def write_goal_deg(self, theta_deg: np.ndarray) -> None:
        with self.lock:
            self._advance()
            self.goal = np.asarray(theta_deg, float).copy()
            self.writes.append((self._elapsed(), self.goal.copy()))

    def _spend(self, dt: float) -> None:
        if self.clock is not None:
            self.clock.sleep(dt)

    def read_position_deg(self) -> np.ndarray:
        with self.lock:
            self._advance()
            self.reads += 1
            if self.reads in self.fail_read_calls or (
                    self.fail_reads_after is not None and self._elapsed() >= self.fail_reads_after):
                self._spend(self.timeout_s)
                raise CommError("no status packet from id 2 (timeout)")
            self._spend(self.io_s)
            if self.expose_alerts:
                self.alerts = {i + 1: int(e != 0) for i, e in enumerate(self.hardware_errors())}
            return np.round(self.x[0] / TICK) * TICK

    def hardware_errors(self) -> list[int]:
        if self.hw_error_after is not None and self._elapsed() >= self.hw_error_after:
            return [0, 0x20, 0]
        return [0, 0, 0]

    def drain_input(self, quiet_s: float) -> int:
        self._spend(quiet_s)
        return 0

    def close(self) -> None:
        pass
