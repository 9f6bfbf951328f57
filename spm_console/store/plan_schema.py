"""Structure of a decoded plan document: every field's type, shape and range.

:func:`plan_from_dict` turns a decoded JSON value into a :class:`~spm_console.core.plan.Plan`
or raises :class:`~spm_console.errors.PlanMismatchError` naming the field and what is
wrong with it. Whether the plan belongs to a profile is checked afterwards
(:func:`spm_console.store.plan_file.check_plan`).
"""

from __future__ import annotations

import math
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from spm_console.core.plan import Plan
from spm_console.core.region import Region
from spm_console.errors import PlanMismatchError, SpmError

F = NDArray[np.float64]

FORMAT = "spm_console.plan"
VERSION = 1
KINDS = ("mvn", "mintime", "synthetic", "homing")
#: Largest N a plan file may hold (2000 s at Ts = 20 ms).
MAX_PLAN_STEPS = 100_000
#: Most half-spaces a region read from a file may have.
MAX_REGION_HALFSPACES = 1000
#: Largest qp_count accepted.
MAX_QP_COUNT = 10**6
#: Keys of extra["check"] that readers format as numbers (a number or null).
CHECK_NUMBERS = ("max_speed_samples_degps", "region_violation_deg", "max_speed_between_degps",
                 "region_violation_between_deg", "speed_excess_degps", "goal_error_deg")


def is_number(v: Any) -> bool:
    """A JSON number (bool is not one)."""
    return type(v) in (int, float)


def _describe(v: Any) -> str:
    text = repr(v)
    return text if len(text) <= 40 else text[:37] + "..."


def matrix(value: Any, where: str, cols: int, max_rows: int, min_rows: int = 1,
           error: type[SpmError] = PlanMismatchError) -> F:
    """A list of ``cols``-number rows (finite floats), else ``error`` naming ``where``."""
    if not isinstance(value, list):
        raise error(f"{where} must be a list of rows of {cols} numbers, got {type(value).__name__}")
    if not min_rows <= len(value) <= max_rows:
        raise error(f"{where} must have {min_rows}..{max_rows} rows, got {len(value)}")
    for k, row in enumerate(value):
        if not (isinstance(row, list) and len(row) == cols and all(is_number(x) for x in row)):
            raise error(f"{where} row {k} must be {cols} numbers, got {_describe(row)}")
    try:
        a = np.asarray(value, float)
    except OverflowError:
        raise error(f"{where} holds a number too large for a float") from None
    if not np.all(np.isfinite(a)):
        k = int(np.argwhere(~np.isfinite(a))[0][0])
        raise error(f"{where} row {k} holds a non-finite value (NaN or infinity)")
    return a


def number(d: dict[str, Any], key: str, src: str, *, positive: bool = False,
           nullable: bool = False, default: float | None = None) -> float:
    """A finite number at ``d[key]`` (null -> NaN when ``nullable``; missing -> ``default``)."""
    if key not in d and default is not None:
        return default
    v = d.get(key)
    if v is None and nullable:
        return float("nan")
    if not is_number(v):
        raise PlanMismatchError(f"{src}: '{key}' must be a number, got {_describe(v)}")
    try:
        f = float(cast(float, v))
    except OverflowError:
        raise PlanMismatchError(f"{src}: '{key}' is too large for a float") from None
    if not math.isfinite(f) or (positive and not f > 0):
        raise PlanMismatchError(f"{src}: '{key}' must be a finite{' positive' if positive else ''} "
                                f"number, got {_describe(v)}")
    return f


def integer(d: dict[str, Any], key: str, src: str, lo: int, hi: int) -> int:
    v = d.get(key)
    if type(v) is not int or not lo <= v <= hi:
        raise PlanMismatchError(f"{src}: '{key}' must be an integer in {lo}..{hi}, got {_describe(v)}")
    return v


def region_of(value: Any, where: str, error: type[SpmError] = PlanMismatchError) -> Region:
    """A region {A (n×3), b (n)} with non-zero normals and at most MAX_REGION_HALFSPACES rows."""
    if not isinstance(value, dict) or "A" not in value or "b" not in value:
        raise error(f"{where} must be an object with 'A' (n×3) and 'b' (n)")
    A = matrix(value["A"], f"{where}.A", 3, MAX_REGION_HALFSPACES, error=error)
    b_raw = value["b"]
    if not isinstance(b_raw, list) or len(b_raw) != len(A):
        raise error(f"{where}.b must be a list of {len(A)} numbers (one per row of A)")
    b = matrix([[x] for x in b_raw], f"{where}.b", 1, MAX_REGION_HALFSPACES, error=error)[:, 0]
    norms = np.linalg.norm(A, axis=1)
    if not np.all(norms > 1e-12):
        k = int(np.argmin(norms))
        raise error(f"{where}.A row {k} is zero: every half-space needs a non-zero normal")
    return Region(A, b)


def _model(value: Any, src: str) -> dict[str, Any]:
    if not isinstance(value, dict) or not {"A", "B", "p", "discretization"} <= value.keys():
        raise PlanMismatchError(f"{src}: 'model' must be an object holding A, B, p and discretization")
    matrix(value["A"], f"{src}: model.A", 2, 2, min_rows=2)
    matrix([value["B"]], f"{src}: model.B", 2, 1)
    number(value, "p", f"{src}: model", positive=True)
    if not isinstance(value["discretization"], str):
        raise PlanMismatchError(f"{src}: model.discretization must be a string")
    return value


def _extra(d: dict[str, Any], src: str) -> dict[str, Any]:
    raw = d.get("extra")
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise PlanMismatchError(f"{src}: 'extra' must be an object, got {_describe(raw)}")
    extra = dict(raw)
    if "n_minus_1_infeasible" in d:
        extra["n_minus_1_infeasible"] = d["n_minus_1_infeasible"]
    for key in ("check", "solver"):
        if extra.get(key) is not None and not isinstance(extra[key], dict):
            raise PlanMismatchError(f"{src}: 'extra.{key}' must be an object or null")
    check = extra.get("check") or {}
    for key in CHECK_NUMBERS:
        if check.get(key) is not None:
            number(check, key, f"{src}: extra.check")
    if "ok" in check and not isinstance(check["ok"], bool):
        raise PlanMismatchError(f"{src}: 'extra.check.ok' must be true or false")
    if extra.get("vmax_degps") is not None:
        number(extra, "vmax_degps", f"{src}: extra", positive=True)
    nm1 = extra.get("n_minus_1_infeasible")
    if nm1 is not None:
        where = f"{src}: n_minus_1_infeasible"
        if not isinstance(nm1, dict):
            raise PlanMismatchError(f"{where} must be an object or null")
        cert = nm1.get("certificate")
        if cert is not None:
            if not isinstance(cert, dict):
                raise PlanMismatchError(f"{where}.certificate must be an object or null")
            if cert.get("excluded_radius") is not None:  # null: ∞ (an exact certificate)
                number(cert, "excluded_radius", f"{where}.certificate")
    return extra


def plan_from_dict(d: Any, src: str = "plan") -> Plan:
    """Validate the structure of a decoded plan document (not its match to a profile)."""
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise PlanMismatchError(f"{src}: not a spm_console plan file (format key missing)")
    if type(d.get("version")) is not int or d["version"] != VERSION:
        raise PlanMismatchError(
            f"{src}: plan format version {_describe(d.get('version'))}, expected {VERSION}")
    kind = d.get("kind")
    if not isinstance(kind, str) or kind not in KINDS:
        raise PlanMismatchError(f"{src}: unknown plan kind {_describe(kind)} (one of {', '.join(KINDS)})")
    arrays = []
    for key in ("reference_deg", "position_deg", "velocity_degps"):
        if key not in d:
            raise PlanMismatchError(f"{src}: missing key '{key}'")
        v = d[key]
        if isinstance(v, list) and v and isinstance(v[0], list) and len(v[0]) != 3:
            raise PlanMismatchError(f"{src}: '{key}' must have 3 columns, got {len(v[0])}")
        arrays.append(matrix(v, f"{src}: '{key}'", 3, MAX_PLAN_STEPS + 1, min_rows=2))
    ref, pos, vel = arrays
    if not (ref.shape == pos.shape == vel.shape):
        raise PlanMismatchError(
            f"{src}: reference_deg, position_deg and velocity_degps must all be (N+1)×3 with N ≥ 1, "
            f"got {ref.shape}, {pos.shape}, {vel.shape}")
    n = d.get("N")
    if type(n) is not int or n != ref.shape[0] - 1:
        raise PlanMismatchError(f"{src}: N = {_describe(n)} but the arrays have {ref.shape[0]} samples")
    ts = number(d, "Ts", src, positive=True)
    if "region" not in d:
        raise PlanMismatchError(f"{src}: missing key 'region'")
    region = region_of(d["region"], f"{src}: region")
    model = _model(d.get("model"), src)
    qp = integer(d, "qp_count", src, 0, MAX_QP_COUNT) if "qp_count" in d else 0
    ph = d.get("profile_hash", "")
    if not isinstance(ph, str) or len(ph) > 256:
        raise PlanMismatchError(f"{src}: 'profile_hash' must be a string (a SHA-256 hex digest)")
    return Plan(kind=kind, Ts=ts, reference_deg=ref, position_deg=pos,  # type: ignore[arg-type]
                velocity_degps=vel, region=region, model=model,
                cost=number(d, "cost", src, nullable=True, default=float("nan")),
                solve_seconds=number(d, "solve_seconds", src, nullable=True, default=float("nan")),
                qp_count=qp, profile_hash=ph, extra=_extra(d, src))
