"""Target files of live following: rows ``t, theta1, theta2, theta3`` (s, deg), or
``t, roll, pitch, yaw`` (deg from home, IK in the home working mode); a header line and ``#``
comments are skipped. Read bounded (size, rows, finite values). Degrees, seconds."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from spm_console.core.targets import MAX_TIMED_TARGETS, TimedTargets
from spm_console.errors import BadInputError
from spm_console.formatting import fmt_deg
from spm_console.profile import Profile
from spm_console.safe_io import MB, read_text

F = NDArray[np.float64]

#: Largest targets file read.
MAX_CSV_BYTES = 10 * MB
#: Largest orientation angle accepted, deg (IK refuses what the wrist cannot reach anyway).
MAX_RPY_DEG = 90.0


def theta_of_rpy(profile: Profile, rpy_deg: F) -> F:
    """Motor angles (deg) for roll, pitch, yaw (deg) from home, home working mode."""
    from spm_console.core.ik import ik_rpy
    from spm_console.models import model_of

    r = np.asarray(rpy_deg, float).reshape(3)
    if not (np.all(np.isfinite(r)) and np.all(np.abs(r) <= MAX_RPY_DEG)):
        raise BadInputError(f"roll, pitch, yaw must be finite and within ±{MAX_RPY_DEG:g}°")
    res = ik_rpy(model_of(profile), *np.radians(r))
    th = np.asarray(res.theta_deg, float)
    if not np.all(np.isfinite(th)):
        raise BadInputError(f"no IK solution for roll, pitch, yaw = {fmt_deg(r)}")
    return th


def read_target_csv(profile: Profile, path: Path, rpy: bool) -> TimedTargets:
    """Rows ``t, a, b, c`` (a header line and ``#`` comments skipped); θ in degrees, or roll,
    pitch, yaw in degrees when ``rpy``."""
    text = read_text(path, "targets file", MAX_CSV_BYTES, BadInputError)
    rows: list[list[float]] = []
    header_allowed = True
    for n, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        cells = [c.strip() for c in line.split(",")]
        try:
            vals = [float(c) for c in cells]
        except ValueError:
            if header_allowed and not rows:  # one header line before the first row
                header_allowed = False
                continue
            raise BadInputError(f"{path}:{n}: four numbers expected (t and three angles)") from None
        if len(vals) != 4:
            raise BadInputError(f"{path}:{n}: four numbers expected (t and three angles), "
                                f"got {len(vals)}")
        if not all(math.isfinite(v) for v in vals):
            raise BadInputError(f"{path}:{n}: t and the angles must be finite numbers")
        rows.append(vals)
        if len(rows) > MAX_TIMED_TARGETS:
            raise BadInputError(f"{path}: more than {MAX_TIMED_TARGETS} targets")
    if not rows:
        raise BadInputError(f"{path}: no targets")
    a = np.asarray(rows, float)
    th = a[:, 1:]
    if rpy:
        th = np.vstack([theta_of_rpy(profile, r) for r in th])
    return TimedTargets(a[:, 0], th)
