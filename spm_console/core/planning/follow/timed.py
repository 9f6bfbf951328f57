"""Timed targets for live following: motor angles from given times on (degrees, seconds)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.errors import BadInputError

F = NDArray[np.float64]

#: Most timed targets one run accepts (a 10-minute file at 50 Hz has 30,000).
MAX_TIMED_TARGETS = 100_000
#: Largest |target angle|, deg: one turn either way (a servo's whole range lies inside).
MAX_TARGET_ABS_DEG = 360.0
#: Latest target time, s: a following lasts at most as long as the longest plan (10 minutes).
MAX_TARGET_TIME_S = 600.0


def check_target_angles(theta_deg: F) -> None:
    """Target angles (deg) within ±:data:`MAX_TARGET_ABS_DEG`; BadInputError otherwise."""
    th = np.asarray(theta_deg, float)
    if not np.all(np.abs(th) <= MAX_TARGET_ABS_DEG):
        worst = float(th.reshape(-1)[np.argmax(np.abs(th).reshape(-1))])
        raise BadInputError(_angles_beyond(worst))


def _angles_beyond(worst: float) -> str:
    return (f"target angles must lie within ±{MAX_TARGET_ABS_DEG:g}° (one turn either way), "
            f"got {worst:.6g}°")


def target_problem(t_s: F, theta_deg: F) -> tuple[int, str] | None:
    """The first target (its index) that breaks a rule of timed targets, and the rule in words:
    finite, angles within ±:data:`MAX_TARGET_ABS_DEG`, times from 0 on, strictly increasing,
    ending by :data:`MAX_TARGET_TIME_S`; None when every row holds. ``t_s`` (n,), ``theta_deg``
    (n, 3)."""
    t = np.asarray(t_s, float).reshape(-1)
    th = np.asarray(theta_deg, float).reshape(-1, 3)
    finite = np.isfinite(t) & np.isfinite(th).all(axis=1)
    order = np.concatenate([[t[0] >= 0], np.diff(t) > 0]) if len(t) else np.ones(0, bool)
    rules = [(~finite, lambda k: "timed targets must be finite numbers"),
             (~(np.abs(th) <= MAX_TARGET_ABS_DEG).all(axis=1),
              lambda k: _angles_beyond(float(th[k][np.argmax(np.abs(th[k]))]))),
             (~order, lambda k: "target times must start at t ≥ 0 and increase strictly"),
             (~(t <= MAX_TARGET_TIME_S), lambda k: (
                 f"target times must end by t = {MAX_TARGET_TIME_S:g} s (10 minutes, like the "
                 f"longest plan), got t = {t[k]:.10g} s"))]
    found = [(int(np.flatnonzero(bad)[0]), words) for bad, words in rules if bad.any()]
    if not found:
        return None
    k, words = min(found, key=lambda f: f[0])
    return k, words(k)


@dataclass(frozen=True)
class TimedTargets:
    """Targets θ (deg) from time t (s since the following began) until the next one."""

    t_s: F
    """(n,) strictly increasing, the first ≥ 0."""
    theta_deg: F
    """(n, 3)."""

    def __post_init__(self) -> None:
        t = np.asarray(self.t_s, float).reshape(-1)
        th = np.asarray(self.theta_deg, float).reshape(-1, 3)
        if not 1 <= len(t) <= MAX_TIMED_TARGETS or th.shape != (len(t), 3):
            raise BadInputError(f"timed targets: 1..{MAX_TIMED_TARGETS} rows of t and three angles")
        problem = target_problem(t, th)
        if problem is not None:
            raise BadInputError(f"target {problem[0] + 1}: {problem[1]}")
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "theta_deg", th)

    def at(self, t: F) -> F:
        """Targets (len(t), 3) at the times ``t``: the last one given at or before each
        (the first one before it begins)."""
        i = np.searchsorted(self.t_s, np.asarray(t, float), side="right") - 1
        return np.asarray(self.theta_deg[np.clip(i, 0, len(self.t_s) - 1)])

    @property
    def end_s(self) -> float:
        return float(self.t_s[-1])
