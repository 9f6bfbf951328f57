"""Structure of a decoded plan document: every field's type, shape and range.

:func:`plan_from_dict` turns a decoded JSON value into a :class:`~spm_console.core.plan.Plan`
or raises :class:`~spm_console.errors.PlanMismatchError` naming the field and what is
wrong with it. Whether the plan belongs to a profile is checked afterwards
(:func:`spm_console.store.plan_file.check_plan`).

The document's "model" becomes a :class:`~spm_console.core.servo.model.ServoModel`; its
"extra" object and the top-level "n_minus_1_infeasible" become the plan's typed
records (:func:`extra_of`: planner options, constraint report, minimum time's N − 1
record, solver details, free-form notes) and are written back under the same keys
(:func:`extra_to_dict`, :func:`record_to_dict`), so plan files keep one format.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from spm_console.core.plan import Plan, PlanOptions, Vec3
from spm_console.core.plan_report import (
    REPORT_NUMBERS,
    Certificate,
    ConstraintReport,
    InfeasibilityRecord,
    SearchStep,
)
from spm_console.core.plan_rules import Rule
from spm_console.core.polytope.region import Region
from spm_console.core.regions.route import RegionRoute
from spm_console.core.servo.model import Discretization, ServoModel
from spm_console.errors import PlanMismatchError, SpmError

F = NDArray[np.float64]

FORMAT = "spm_console.plan"
VERSION = 1
KINDS = ("mvn", "mintime", "synthetic", "homing", "jog", "experiment")
#: Largest N a plan file may hold (2000 s at Ts = 20 ms).
MAX_PLAN_STEPS = 100_000
#: Most half-spaces a region read from a file may have.
MAX_REGION_HALFSPACES = 1000
#: Most regions a plan's route may pass through.
MAX_ROUTE_REGIONS = 64
#: Largest qp_count accepted.
MAX_QP_COUNT = 10**6
#: Most steps of a minimum-time search record read from a file (a search takes a few dozen).
MAX_SEARCH_STEPS = 1000
#: Largest sub-sample count K and between-sample points per interval read from a file.
MAX_POINTS = 10**6
#: Keys of a plan file's "extra" object that hold what the planner was asked (PlanOptions).
OPTION_KEYS = ("start_deg", "goal_deg", "vmax_degps", "intersample", "hold_first",
               "reference_limits_deg")
#: Keys of "extra" read into typed fields; any other key is kept in Plan.notes.
TYPED_EXTRA_KEYS = (*OPTION_KEYS, "check", "solver", "search_seconds", "n_minus_1_infeasible")
DISCRETIZATIONS = ("zoh", "tustin")


#: What a plan file's ``extra.check.runtime_rule`` may hold.
RUNTIME_RULES = frozenset({""} | {r.value for r in Rule})


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


def _model(value: Any, src: str, ts: float) -> ServoModel:
    """The servo model {A, B, p, discretization[, Ts][, zeta, delay_s]}; Ts, when present, is
    the plan's; zeta and delay_s (an identified model) default to the paper's 1 and 0."""
    if not isinstance(value, dict) or not {"A", "B", "p", "discretization"} <= value.keys():
        raise PlanMismatchError(f"{src}: 'model' must be an object holding A, B, p and discretization")
    A = matrix(value["A"], f"{src}: model.A", 2, 2, min_rows=2)
    B = matrix([value["B"]], f"{src}: model.B", 2, 1)[0]
    p = number(value, "p", f"{src}: model", positive=True)
    method = value["discretization"]
    if not isinstance(method, str):
        raise PlanMismatchError(f"{src}: model.discretization must be a string")
    if method not in DISCRETIZATIONS:
        raise PlanMismatchError(f"{src}: model.discretization must be one of "
                                f"{', '.join(DISCRETIZATIONS)}, got {_describe(method)}")
    if "Ts" in value:
        mts = number(value, "Ts", f"{src}: model", positive=True)
        if not math.isclose(mts, ts, rel_tol=0, abs_tol=1e-12):
            raise PlanMismatchError(f"{src}: model.Ts = {mts:g} s but the plan's Ts is {ts:g} s")
    zeta = number(value, "zeta", f"{src}: model", positive=True) if "zeta" in value else 1.0
    delay = number(value, "delay_s", f"{src}: model") if "delay_s" in value else 0.0
    if not 0.0 <= delay < ts:
        raise PlanMismatchError(f"{src}: model.delay_s = {delay:g} s must lie in [0, Ts)")
    return ServoModel(p=p, ts=ts, method=cast(Discretization, method), A=A, B=B, zeta=zeta,
                      delay_s=delay)


@dataclass(frozen=True)
class Extra:
    """The typed content of a plan document's "extra" and "n_minus_1_infeasible"."""

    options: PlanOptions | None
    check: ConstraintReport | None
    certificate: InfeasibilityRecord | None
    solver: dict[str, Any] | None
    notes: dict[str, Any]


def _vec3(value: Any, where: str) -> Vec3:
    if not (isinstance(value, list) and len(value) == 3 and all(is_number(x) for x in value)):
        raise PlanMismatchError(f"{where} must be 3 numbers, got {_describe(value)}")
    a = matrix([value], where, 3, 1)[0]
    return float(a[0]), float(a[1]), float(a[2])


def _flag(d: dict[str, Any], key: str, where: str, default: bool) -> bool:
    """A JSON true/false at ``d[key]`` (missing -> ``default``); ``where`` names ``d``."""
    v = d.get(key, default)
    if not isinstance(v, bool):
        raise PlanMismatchError(f"{where}: '{key}' must be true or false, got {_describe(v)}")
    return v


def _options(extra: dict[str, Any], src: str) -> PlanOptions | None:
    """What the planner was asked; None when "extra" holds none of :data:`OPTION_KEYS`."""
    if not any(k in extra for k in OPTION_KEYS):
        return None
    where = f"{src}: extra"
    vmax = None
    if extra.get("vmax_degps") is not None:
        vmax = number(extra, "vmax_degps", where, positive=True)
    limits = extra.get("reference_limits_deg")
    lo_hi: tuple[Vec3 | None, Vec3 | None] | None = None
    if limits is not None:
        if not (isinstance(limits, list) and len(limits) == 2):
            raise PlanMismatchError(f"{where}: 'reference_limits_deg' must be [lower, upper] "
                                    f"(each 3 numbers or null) or null, got {_describe(limits)}")
        lo, hi = (None if v is None else _vec3(v, f"{where}.reference_limits_deg[{i}]")
                  for i, v in enumerate(limits))
        lo_hi = None if lo is None and hi is None else (lo, hi)
    return PlanOptions(
        start_deg=_vec3(extra.get("start_deg"), f"{where}.start_deg"),
        goal_deg=_vec3(extra.get("goal_deg"), f"{where}.goal_deg"),
        vmax_degps=vmax,
        intersample=integer(extra, "intersample", where, 1, MAX_POINTS)
        if "intersample" in extra else 1,
        hold_first=_flag(extra, "hold_first", where, True),
        reference_limits_deg=lo_hi)


def _check(value: Any, src: str) -> ConstraintReport | None:
    """The constraint report; a number it lacks (or holds as null) is NaN, a missing 'ok' false."""
    if value is None:
        return None
    if not isinstance(value, dict):
        raise PlanMismatchError(f"{src}: 'extra.check' must be an object or null")
    where = f"{src}: extra.check"
    nums = {k: number(value, k, where, nullable=True, default=math.nan) for k in REPORT_NUMBERS}
    pts = integer(value, "points_per_interval", where, 0, MAX_POINTS) \
        if value.get("points_per_interval") is not None else 0
    if not isinstance(value.get("ok", False), bool):
        raise PlanMismatchError(f"{src}: 'extra.check.ok' must be true or false")
    rule = value.get("runtime_rule", "")
    if not isinstance(rule, str) or rule not in RUNTIME_RULES:
        raise PlanMismatchError(f"{src}: 'extra.check.runtime_rule' must be empty or one of the "
                                f"runtime's rules, got {_describe(rule)}")
    return ConstraintReport(**nums, points_per_interval=pts, ok=value.get("ok", False),
                            runtime_rule=rule)


def _certificate(value: Any, where: str) -> Certificate | None:
    """A Farkas certificate; excluded_radius null is ∞ (an exact certificate)."""
    if value is None:
        return None
    if not isinstance(value, dict):
        raise PlanMismatchError(f"{where}.certificate must be an object or null")
    where = f"{where}.certificate"
    radius = math.inf if value.get("excluded_radius") is None else \
        number(value, "excluded_radius", where)
    solver = value.get("solver", "")
    if not isinstance(solver, str):
        raise PlanMismatchError(f"{where}: 'solver' must be a string, got {_describe(solver)}")
    return Certificate(
        residual_l1=number(value, "residual_l1", where, nullable=True, default=math.nan),
        cone_violation=number(value, "cone_violation", where, nullable=True, default=math.nan),
        excluded_radius=radius,
        rows=integer(value, "rows", where, 0, 10**9) if value.get("rows") is not None else 0,
        valid=_flag(value, "valid", where, False), solver=solver)


def _search(value: Any, where: str) -> tuple[SearchStep, ...]:
    """The minimum-time search trace: every N examined, with its verdict."""
    if value is None:
        return ()
    if not isinstance(value, list) or len(value) > MAX_SEARCH_STEPS:
        raise PlanMismatchError(f"{where}.search must be a list of at most {MAX_SEARCH_STEPS} "
                                f"steps, got {_describe(value)}")
    steps = []
    for k, e in enumerate(value):
        at = f"{where}.search[{k}]"
        if not (isinstance(e, dict) and isinstance(e.get("verdict"), str)
                and isinstance(e.get("method"), str)):
            raise PlanMismatchError(f"{at} must be an object with N, verdict, method and seconds")
        steps.append(SearchStep(N=integer(e, "N", at, 0, 10**9), verdict=e["verdict"],
                                method=e["method"],
                                seconds=number(e, "seconds", at, nullable=True, default=math.nan)))
    return tuple(steps)


def _record(value: Any, extra: dict[str, Any], src: str, n: int) -> InfeasibilityRecord | None:
    """Minimum time's N − 1 record ("n_minus_1_infeasible", and extra.search_seconds)."""
    if value is None:
        return None
    where = f"{src}: n_minus_1_infeasible"
    if not isinstance(value, dict):
        raise PlanMismatchError(f"{where} must be an object or null")
    cert = _certificate(value.get("certificate"), where)
    if type(value.get("N")) is not int or value["N"] != n - 1:
        raise PlanMismatchError(f"{where}.N must be the plan's N − 1 = {n - 1}, "
                                f"got {_describe(value.get('N'))}")
    if value.get("feasible", False) is not False:
        raise PlanMismatchError(f"{where}.feasible must be false")
    scope = value.get("scope", "")
    if not isinstance(scope, str) or len(scope) > 500:
        raise PlanMismatchError(f"{where}.scope must be a string of at most 500 characters")
    return InfeasibilityRecord(
        N=n - 1, certificate=cert, search=_search(value.get("search"), where),
        search_seconds=number(extra, "search_seconds", f"{src}: extra", nullable=True,
                              default=math.nan), scope=scope)


def extra_of(d: dict[str, Any], src: str, n: int) -> Extra:
    """Validate "extra" (and the top-level "n_minus_1_infeasible") of a plan with N = n."""
    raw = d.get("extra")
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise PlanMismatchError(f"{src}: 'extra' must be an object, got {_describe(raw)}")
    solver = raw.get("solver")
    if solver is not None and not isinstance(solver, dict):
        raise PlanMismatchError(f"{src}: 'extra.solver' must be an object or null")
    check = _check(raw.get("check"), src)
    options = _options(raw, src)
    record = _record(d.get("n_minus_1_infeasible", raw.get("n_minus_1_infeasible")), raw, src, n)
    notes = {k: v for k, v in raw.items() if k not in TYPED_EXTRA_KEYS}
    return Extra(options, check, record, solver, notes)


def options_to_dict(options: PlanOptions) -> dict[str, Any]:
    """The "extra" keys of what the planner was asked."""
    lim = options.reference_limits_deg
    return {"start_deg": list(options.start_deg), "goal_deg": list(options.goal_deg),
            "vmax_degps": options.vmax_degps, "intersample": options.intersample,
            "hold_first": options.hold_first,
            "reference_limits_deg": None if lim is None else
            [None if v is None else list(v) for v in lim]}


def record_to_dict(record: InfeasibilityRecord) -> dict[str, Any]:
    """The document's "n_minus_1_infeasible" object (search_seconds goes to "extra")."""
    return {"N": record.N, "feasible": False,
            "certificate": None if record.certificate is None else record.certificate.to_dict(),
            "search": [s.to_dict() for s in record.search],
            **({"scope": record.scope} if record.scope else {})}


def route_to_dict(route: RegionRoute) -> dict[str, Any]:
    """The document's "route" object (plans across several regions only)."""
    return {"regions": [r.to_dict() for r in route.regions],
            "switch_samples": list(route.switch), "labels": list(route.labels)}


def route_of(value: Any, first: Region, src: str, n: int) -> RegionRoute | None:
    """A plan's "route": 2..MAX_ROUTE_REGIONS regions, switch samples strictly increasing
    inside 1..N−1, the first region equal to the plan's "region"."""
    if value is None:
        return None
    where = f"{src}: route"
    if not isinstance(value, dict):
        raise PlanMismatchError(f"{where} must be an object or null")
    regs = value.get("regions")
    if not isinstance(regs, list) or not 2 <= len(regs) <= MAX_ROUTE_REGIONS:
        raise PlanMismatchError(f"{where}.regions must be a list of 2..{MAX_ROUTE_REGIONS} regions")
    regions = tuple(region_of(r, f"{where}.regions[{i}]") for i, r in enumerate(regs))
    sw = value.get("switch_samples")
    if (not isinstance(sw, list) or len(sw) != len(regions) - 1
            or any(type(k) is not int or not 0 < k < n for k in sw)
            or any(b <= a for a, b in itertools.pairwise(sw))):
        raise PlanMismatchError(f"{where}.switch_samples must be {len(regions) - 1} strictly "
                                f"increasing samples inside 1..{n - 1}")
    labels = value.get("labels", [])
    if (not isinstance(labels, list) or (labels and len(labels) != len(regions))
            or any(not isinstance(x, str) or len(x) > 100 for x in labels)):
        raise PlanMismatchError(f"{where}.labels must be one short string per region")
    if not (np.array_equal(regions[0].A, first.A) and np.array_equal(regions[0].b, first.b)):
        raise PlanMismatchError(f"{where}: its first region must be the plan's 'region'")
    return RegionRoute(regions, tuple(sw), tuple(labels))


def extra_to_dict(plan: Plan) -> dict[str, Any]:
    """The document's "extra" object: options, check, solver, search_seconds, then the notes."""
    ex: dict[str, Any] = {} if plan.options is None else options_to_dict(plan.options)
    if plan.check is not None:
        ex["check"] = plan.check.to_dict()
    if plan.solver is not None:
        ex["solver"] = plan.solver
    if plan.certificate is not None:
        ex["search_seconds"] = plan.certificate.search_seconds
    for k, v in plan.notes.items():
        ex.setdefault(k, v)
    return ex


def plan_from_dict(d: Any, src: str = "plan") -> Plan:
    """Validate the structure of a decoded plan document (not its match to a profile)."""
    if not isinstance(d, dict) or "format" not in d:
        raise PlanMismatchError(f"{src}: not a spm_console plan file (format key missing)")
    if d["format"] != FORMAT:
        raise PlanMismatchError(f"{src}: not a spm_console plan file (format "
                                f"{_describe(d['format'])}, expected {FORMAT!r})")
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
    model = _model(d.get("model"), src, ts)
    qp = integer(d, "qp_count", src, 0, MAX_QP_COUNT) if "qp_count" in d else 0
    ph = d.get("profile_hash", "")
    if not isinstance(ph, str) or len(ph) > 256:
        raise PlanMismatchError(f"{src}: 'profile_hash' must be a string (a SHA-256 hex digest)")
    cost = number(d, "cost", src, nullable=True, default=float("nan"))
    solve_seconds = number(d, "solve_seconds", src, nullable=True, default=float("nan"))
    ex = extra_of(d, src, n)
    route = route_of(d.get("route"), region, src, n)
    return Plan(kind=kind, Ts=ts, reference_deg=ref, position_deg=pos,  # type: ignore[arg-type]
                velocity_degps=vel, region=region, model=model, cost=cost,
                solve_seconds=solve_seconds, qp_count=qp, profile_hash=ph,
                options=ex.options, check=ex.check,
                certificate=ex.certificate, solver=ex.solver, notes=ex.notes, route=route)
