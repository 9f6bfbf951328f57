"""The emulated wrist's truth as CSV, for tests and benchmarks (``emulate --truth-log``; the
product never reads it).

One row every :data:`TRUTH_LOG_PERIOD_S` of the emulator's clock (100 Hz), the wrist stepped to
that instant first: ``t_s`` (s since the emulated servos powered on), the platform's orientation
``qw, qx, qy, qz`` (unit, w ≥ 0, world ← platform: with a level base, the forward kinematics'
R) and the true joint angles ``theta1_deg..theta3_deg`` at the output shafts. Bounded: the log
ends by itself after :data:`MAX_TRUTH_LOG_S` (one hour, 360,000 rows, about 30 MB); flushed
every :data:`FLUSH_EVERY_ROWS` rows (a second) and when closed.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

#: Interval between rows, s (100 Hz).
TRUTH_LOG_PERIOD_S = 0.01
#: Longest span a truth log covers, s: the log ends by itself there.
MAX_TRUTH_LOG_S = 3600.0
#: Rows written before the file is flushed (a second's).
FLUSH_EVERY_ROWS = 100
HEADER = ("t_s", "qw", "qx", "qy", "qz", "theta1_deg", "theta2_deg", "theta3_deg")


class TruthLog:
    """A truth log being written (``path`` replaced if it exists). Not thread-safe: the
    emulator writes it under its lock."""

    def __init__(self, path: str | Path, period_s: float = TRUTH_LOG_PERIOD_S,
                 max_s: float = MAX_TRUTH_LOG_S) -> None:
        self.path = Path(path)
        self.period_s = period_s
        self.max_rows = round(max_s / period_s)
        self.rows = 0
        self.full = False
        """Whether the log reached its length limit (and ended)."""
        self._file: TextIO | None = open(self.path, "w", encoding="utf-8", newline="")  # noqa: SIM115
        self._file.write(",".join(HEADER) + "\n")

    @property
    def open(self) -> bool:
        return self._file is not None

    @property
    def next_s(self) -> float:
        """When the next row is due, s since power-on."""
        return self.rows * self.period_s

    def write(self, t_s: float, quat_wxyz: Sequence[float], theta_deg: Sequence[float]) -> None:
        """One row: time (s since power-on), world ← platform quaternion, θ (deg)."""
        if self._file is None:
            return
        q = ",".join(f"{float(x):.9f}" for x in quat_wxyz)
        th = ",".join(f"{float(x):.6f}" for x in theta_deg)
        self._file.write(f"{t_s:.6f},{q},{th}\n")
        self.rows += 1
        if self.rows >= self.max_rows:
            self.full = True
            self.close()
        elif self.rows % FLUSH_EVERY_ROWS == 0:
            self._file.flush()

    def close(self) -> None:
        """Flush and close (idempotent)."""
        if self._file is not None:
            f, self._file = self._file, None
            f.close()
