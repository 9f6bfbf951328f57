"""Target files of live following: rows ``t, theta1, theta2, theta3`` (s, deg), or
``t, roll, pitch, yaw`` (deg from home, IK in the home working mode); ``#`` comments are
skipped, and so is a first line of names only (a header: none of its cells is written as a
number). Every other line is four plain decimal numbers (:mod:`spm_console.numbers`): a typo
is an error at its line, never taken for a header. Read bounded (size, rows, finite values,
times). Degrees, seconds."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from spm_console.config.schema import Profile
from spm_console.core.planning.follow.timed import MAX_TIMED_TARGETS, TimedTargets
from spm_console.errors import BadInputError
from spm_console.formatting import fmt_deg
from spm_console.numbers import numeric_rows
from spm_console.safe_io import MB, read_text

F = NDArray[np.float64]

#: Largest targets file read.
MAX_CSV_BYTES = 10 * MB
#: Largest orientation angle accepted, deg (IK refuses what the wrist cannot reach anyway).
MAX_RPY_DEG = 90.0


def theta_of_rpy(profile: Profile, rpy_deg: F) -> F:
    """Motor angles (deg) for roll, pitch, yaw (deg) from home, home working mode."""
    from spm_console.config.models import model_of
    from spm_console.core.kinematics.ik import ik_rpy

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
    for _n, vals in numeric_rows(text, str(path), 4, "t and three angles"):
        rows.append(vals)
        if len(rows) > MAX_TIMED_TARGETS:
            raise BadInputError(f"{path}: more than {MAX_TIMED_TARGETS} targets")
    if not rows:
        raise BadInputError(f"{path}: no targets")
    a = np.asarray(rows, float)
    th = a[:, 1:]
    if rpy:
        th = np.vstack([theta_of_rpy(profile, r) for r in th])
    try:
        return TimedTargets(a[:, 0], th)
    except BadInputError as exc:
        raise BadInputError(f"{path}: {exc.message}") from None
