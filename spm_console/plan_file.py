"""Plan files: JSON with the SPEC §5 keys, checked against the profile on load.

A plan is valid for a profile when the sections that shape it — geometry, home,
links, workspace and servo — are unchanged (:func:`plan_hash`); the bus port,
safety thresholds or UI settings may change without invalidating plans. Loading
also checks Ts and the servo model, re-simulates the model under the references
and compares with the stored positions and velocities, so a hand-edited or
truncated file is refused with :class:`~spm_console.errors.PlanMismatchError`.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from spm_console.core.plan import Plan
from spm_console.core.region import Region
from spm_console.core.servo_model import discretize, simulate
from spm_console.errors import PlanMismatchError
from spm_console.jsonutil import to_jsonable
from spm_console.profile import Profile

FORMAT = "spm_console.plan"
VERSION = 1
#: Profile sections a plan depends on.
PLAN_SECTIONS = ("geometry", "home", "links", "workspace", "servo")
#: Stored positions/velocities must match the re-simulated model to this (deg, deg/s).
CONSISTENCY_TOL = 1e-6
KINDS = ("mvn", "mintime", "synthetic", "homing")


def plan_hash(profile: Profile) -> str:
    """SHA-256 of the profile sections a plan depends on."""
    return profile.section_digest(*PLAN_SECTIONS)


def plan_to_dict(plan: Plan) -> dict[str, Any]:
    """The JSON document of a plan (SPEC §5 keys first)."""
    d: dict[str, Any] = {
        "format": FORMAT,
        "version": VERSION,
        "kind": plan.kind,
        "Ts": plan.Ts,
        "N": plan.N,
        "duration_s": plan.duration_s,
        "reference_deg": plan.reference_deg,
        "position_deg": plan.position_deg,
        "velocity_degps": plan.velocity_degps,
        "cost": plan.cost,
        "solve_seconds": plan.solve_seconds,
        "qp_count": plan.qp_count,
        "region": plan.region.to_dict(),
        "model": plan.model,
        "profile_hash": plan.profile_hash,
    }
    if "n_minus_1_infeasible" in plan.extra:
        d["n_minus_1_infeasible"] = plan.extra["n_minus_1_infeasible"]
    d["extra"] = {k: v for k, v in plan.extra.items() if k != "n_minus_1_infeasible"}
    return dict(to_jsonable(d))


def save_plan(plan: Plan, path: str | Path) -> None:
    """Write the plan atomically (temporary file + rename)."""
    p = Path(path)
    text = json.dumps(plan_to_dict(plan), indent=1)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", dir=str(p.parent) or ".")
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text + "\n")
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _array(d: dict[str, Any], key: str, src: str, cols: int | None = 3) -> np.ndarray:
    if key not in d:
        raise PlanMismatchError(f"{src}: missing key '{key}'")
    try:
        a = np.asarray(d[key], float)
    except (TypeError, ValueError):
        raise PlanMismatchError(f"{src}: '{key}' is not a numeric array") from None
    if cols is not None and (a.ndim != 2 or a.shape[1] != cols):
        raise PlanMismatchError(f"{src}: '{key}' must have {cols} columns, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise PlanMismatchError(f"{src}: '{key}' holds non-finite values")
    return a


def plan_from_dict(d: Any, src: str = "plan") -> Plan:
    """Validate the structure of a decoded plan document (not its match to a profile)."""
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise PlanMismatchError(f"{src}: not a spm_console plan file (format key missing)")
    if d.get("version") != VERSION:
        raise PlanMismatchError(f"{src}: plan format version {d.get('version')}, expected {VERSION}")
    kind = d.get("kind")
    if kind not in KINDS:
        raise PlanMismatchError(f"{src}: unknown plan kind {kind!r}")
    ref = _array(d, "reference_deg", src)
    pos = _array(d, "position_deg", src)
    vel = _array(d, "velocity_degps", src)
    if not (ref.shape == pos.shape == vel.shape) or ref.shape[0] < 2:
        raise PlanMismatchError(
            f"{src}: reference_deg, position_deg and velocity_degps must all be (N+1)×3 with N ≥ 1, "
            f"got {ref.shape}, {pos.shape}, {vel.shape}")
    n = d.get("N")
    if n != ref.shape[0] - 1:
        raise PlanMismatchError(f"{src}: N = {n} but the arrays have {ref.shape[0]} samples")
    ts = d.get("Ts")
    if not isinstance(ts, int | float) or not ts > 0:
        raise PlanMismatchError(f"{src}: Ts must be a positive number of seconds, got {ts!r}")
    try:
        region = Region.from_dict(d["region"])
    except (KeyError, TypeError, ValueError) as exc:
        raise PlanMismatchError(f"{src}: bad region: {exc}") from None
    model = d.get("model")
    if not isinstance(model, dict) or not {"A", "B", "p", "discretization"} <= model.keys():
        raise PlanMismatchError(f"{src}: 'model' must hold A, B, p and discretization")
    extra = dict(d.get("extra") or {})
    if "n_minus_1_infeasible" in d:
        extra["n_minus_1_infeasible"] = d["n_minus_1_infeasible"]

    def num(key: str) -> float:
        v = d.get(key)
        return float(v) if isinstance(v, int | float) else float("nan")

    return Plan(kind=kind, Ts=float(ts), reference_deg=ref, position_deg=pos, velocity_degps=vel,
                region=region, model=model, cost=num("cost"), solve_seconds=num("solve_seconds"),
                qp_count=int(d.get("qp_count") or 0), profile_hash=str(d.get("profile_hash", "")),
                extra=extra)


def check_plan(plan: Plan, profile: Profile, src: str = "plan") -> None:
    """Refuse a plan that does not belong to ``profile`` or is internally inconsistent."""
    want = plan_hash(profile)
    if plan.profile_hash != want:
        raise PlanMismatchError(
            f"{src}: made for another profile or profile version (plan hash "
            f"{plan.profile_hash[:12] or 'none'}…, profile '{profile.name}' hash {want[:12]}…); "
            "re-plan with this profile")
    sv = profile.servo
    if not math.isclose(plan.Ts, sv.ts_s, rel_tol=0, abs_tol=1e-12):
        raise PlanMismatchError(f"{src}: Ts = {plan.Ts} s but the profile's Ts is {sv.ts_s} s")
    m = plan.model
    if m.get("discretization") != sv.discretization or not isinstance(m.get("p"), int | float) \
            or not math.isclose(float(m["p"]), sv.p, rel_tol=1e-12):
        raise PlanMismatchError(
            f"{src}: servo model p = {m.get('p')}, {m.get('discretization')} but the profile has "
            f"p = {sv.p}, {sv.discretization}")
    ref_model = discretize(sv.p, sv.ts_s, sv.discretization)
    try:
        A = np.asarray(m["A"], float).reshape(2, 2)
        B = np.asarray(m["B"], float).reshape(2)
    except (TypeError, ValueError):
        raise PlanMismatchError(f"{src}: model A must be 2×2 and B of length 2") from None
    if not (np.allclose(A, ref_model.A, rtol=0, atol=1e-9)
            and np.allclose(B, ref_model.B, rtol=0, atol=1e-9)):
        raise PlanMismatchError(f"{src}: model matrices A, B differ from the profile's servo model")
    x0 = np.column_stack([plan.position_deg[0], plan.velocity_degps[0]])
    xs = simulate(ref_model, x0, plan.reference_deg)
    err = max(float(np.abs(xs[..., 0] - plan.position_deg).max()),
              float(np.abs(xs[..., 1] - plan.velocity_degps).max()))
    if err > CONSISTENCY_TOL:
        raise PlanMismatchError(
            f"{src}: positions/velocities disagree with the servo model under the references by "
            f"{err:.3g} (corrupt or edited file)")
    if plan.kind in ("mvn", "mintime"):
        viol = float(plan.region.violation_deg(plan.position_deg).max())
        if viol > 1e-6:
            raise PlanMismatchError(f"{src}: planned positions leave the plan's region P by {viol:.3g}°")
        if float(np.abs(plan.velocity_degps[-1]).max()) > 1e-6 or \
                float(np.abs(plan.reference_deg[-1] - plan.position_deg[-1]).max()) > 1e-6:
            raise PlanMismatchError(f"{src}: the plan does not end at rest on its final reference")


def load_plan(path: str | Path, profile: Profile) -> Plan:
    """Read a plan file and check it against ``profile``; raises PlanMismatchError."""
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as exc:
        raise PlanMismatchError(f"{p}: cannot read plan: {exc.strerror or exc}") from None
    try:
        d = json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise PlanMismatchError(f"{p}: not valid JSON (corrupt plan file): {exc}") from None
    plan = plan_from_dict(d, str(p))
    check_plan(plan, profile, str(p))
    return plan
