"""Reading a sweep's table: the best designs per figure of merit, the Pareto front of two,
and one design's profile (``design show``, ``design profile``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from spm_console.config.edit import with_values
from spm_console.config.schema import Profile
from spm_console.design.evaluate import design_profile
from spm_console.design.spec import PARAMETERS
from spm_console.errors import BadInputError

#: The figures a design is ranked by: name -> True when larger is better.
RANKED: dict[str, bool] = {
    "feasible_fraction": True, "feasible_volume_deg3": True, "p_volume_deg3": True,
    "p_coverage": True, "zeta_mean": True, "zeta_min": True, "clearance_min_mm": True,
    "clearance_home_mm": True, "tilt_cone_deg": True, "torsion_range_deg": True,
    "pairs_planned": True, "seconds": False,
}


@dataclass(frozen=True)
class Ranked:
    """One design in a ranking."""

    index: int
    value: float
    params: dict[str, float]


def _valid(cols: dict[str, list[Any]], metric: str) -> NDArray[np.bool_]:
    ok = np.asarray(cols["ok"], bool)
    v = np.asarray([math.nan if x is None else x for x in cols[metric]], float)
    return ok & np.isfinite(v)


def check_metric(name: str, what: str) -> None:
    if name not in RANKED:
        raise BadInputError(f"{what} {name!r}: not a figure of merit (allowed: {', '.join(RANKED)})")


def best(cols: dict[str, list[Any]], names: tuple[str, ...], metric: str, top: int) -> list[Ranked]:
    """The ``top`` designs by ``metric`` (the better first; ties by index)."""
    check_metric(metric, "--metric")
    keep = np.flatnonzero(_valid(cols, metric))
    sign = -1.0 if RANKED[metric] else 1.0
    order = sorted(keep, key=lambda i: (sign * float(cols[metric][i]), int(cols["index"][i])))
    return [Ranked(int(cols["index"][i]), float(cols[metric][i]),
                   {n: float(cols[n][i]) for n in names}) for i in order[:top]]


def pareto(cols: dict[str, list[Any]], x: str, y: str) -> NDArray[np.int64]:
    """Rows of the designs no other design beats on both ``x`` and ``y`` (each in its own
    better direction), sorted by x."""
    check_metric(x, "--pareto")
    check_metric(y, "--pareto")
    keep = np.flatnonzero(_valid(cols, x) & _valid(cols, y))
    sx = 1.0 if RANKED[x] else -1.0
    sy = 1.0 if RANKED[y] else -1.0
    X = sx * np.asarray([cols[x][i] for i in keep], float)
    Y = sy * np.asarray([cols[y][i] for i in keep], float)
    front = []
    for k in range(len(keep)):
        dx, dy = X - X[k], Y - Y[k]
        if not np.any((dx >= 0) & (dy >= 0) & ((dx > 0) | (dy > 0))):  # no design beats k
            front.append(k)
    rows = keep[front]
    return rows[np.argsort([cols[x][i] for i in rows], kind="stable")]


def row_of(cols: dict[str, list[Any]], index: int) -> int:
    """The table row of design ``index`` (BadInputError when the table has none)."""
    for r, k in enumerate(cols["index"]):
        if int(k) == index:
            return r
    raise BadInputError(f"design {index}: not in this sweep's table (done: {len(cols['index'])} "
                        f"designs)")


def design_profile_text(folder: Path, base_text: str, names: tuple[str, ...],
                        cols: dict[str, list[Any]], index: int) -> tuple[str, Profile]:
    """The base profile's TOML with design ``index``'s values and home mode, each commented
    with the sweep it came from; validated (ProfileError when it does not load)."""
    r = row_of(cols, index)
    if not cols["ok"][r]:
        raise BadInputError(f"design {index} could not be built: {cols['reason'][r]}")
    params = {n: float(cols[n][r]) for n in names}
    source = f"design {index} of {folder}"
    prof = design_profile(base_text, params, source)
    values: dict[tuple[str, str], Any] = {(PARAMETERS[n], n): v for n, v in params.items()}
    values[("home", "sign_seed")] = list(prof.home.sign_seed)
    return with_values(base_text, values, f"[design sweep] design {index} of {folder}", source)
