"""Timed targets of live following, and their files: rows ``t, theta1, theta2, theta3`` (s,
deg), or ``t, roll, pitch, yaw`` (deg from home, IK in the home working mode); ``#`` comments
are skipped, and so is a first line of names only (a header: none of its cells is written as a
number). Every other line is four plain decimal numbers (:mod:`spm_console.numbers`): a typo
is an error at its line, never taken for a header. Read bounded (size, rows, finite values,
times). One rule for every source of targets: the CLI's files, a script's inline rows or file,
UDP messages (:func:`theta_of_rpy`). Degrees, seconds."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.ik import ik_rpy
from spm_console.core.planning.follow.timed import MAX_TIMED_TARGETS, TimedTargets, target_problem
from spm_console.errors import BadInputError, SpmError
from spm_console.formatting import fmt_deg
from spm_console.input_rules import rpy_angles
from spm_console.numbers import numeric_rows
from spm_console.safe_io import MB, read_text

F = NDArray[np.float64]

#: Largest targets file read.
MAX_CSV_BYTES = 10 * MB


def theta_of_rpy(profile: Profile, rpy_deg: F | Sequence[float], where: str = "target") -> F:
    """Motor angles (deg) for roll, pitch, yaw (deg) from home, home working mode: each angle
    within ±360° (:data:`~spm_console.input_rules.RPY`, as ``ik --rpy``), an orientation IK
    places (else UnreachableError, exit 5). What lies beyond the servo limits or the region
    is the follower's to project, as for targets given as θ. Refusals begin with ``where``."""
    r = rpy_angles(list(np.asarray(rpy_deg, float).reshape(-1)), f"{where}:")
    try:
        th = np.asarray(ik_rpy(model_of(profile), *np.radians(r)).theta_deg, float)
    except SpmError as exc:
        raise exc.at(f"{where}: roll, pitch, yaw = {fmt_deg(r)}") from None
    if not np.all(np.isfinite(th)):
        raise BadInputError(f"{where}: roll, pitch, yaw = {fmt_deg(r)} has no IK solution")
    return th


def timed_targets(profile: Profile, rows: Sequence[tuple[str, Sequence[float]]],
                  rpy: bool) -> TimedTargets:
    """Timed targets from rows ``(where, [t, a, b, c])``: θ in degrees, or roll, pitch, yaw
    when ``rpy``; a refusal begins with the row's ``where`` (a file's line, a script's row)."""
    if not 1 <= len(rows) <= MAX_TIMED_TARGETS:
        raise BadInputError(f"1..{MAX_TIMED_TARGETS} targets expected, got {len(rows)}")
    a = np.asarray([r for _, r in rows], float).reshape(len(rows), 4)
    th = a[:, 1:]
    if rpy:
        th = np.vstack([theta_of_rpy(profile, v, where)
                        for (where, _), v in zip(rows, th, strict=True)])
    problem = target_problem(a[:, 0], th)
    if problem is not None:
        raise BadInputError(f"{rows[problem[0]][0]}: {problem[1]}")
    return TimedTargets(a[:, 0], th)


def read_target_csv(profile: Profile, path: Path, rpy: bool) -> TimedTargets:
    """Rows ``t, a, b, c`` (a header line and ``#`` comments skipped); θ in degrees, or roll,
    pitch, yaw in degrees when ``rpy``. Refusals name the file and the line."""
    text = read_text(path, "targets file", MAX_CSV_BYTES, BadInputError)
    rows: list[tuple[str, list[float]]] = []
    for n, vals in numeric_rows(text, str(path), 4, "t and three angles"):
        rows.append((f"{path}:{n}", vals))
        if len(rows) > MAX_TIMED_TARGETS:
            raise BadInputError(f"{path}: more than {MAX_TIMED_TARGETS} targets")
    if not rows:
        raise BadInputError(f"{path}: no targets")
    return timed_targets(profile, rows, rpy)
