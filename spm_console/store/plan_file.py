"""Plan files: JSON with the documented keys, checked against the profile on load.

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
from pathlib import Path
from typing import Any

import numpy as np

from spm_console.config.models import servo_model_of
from spm_console.config.schema import Profile
from spm_console.core.plan import Plan
from spm_console.core.servo.model import simulate
from spm_console.errors import BadInputError, PlanMismatchError
from spm_console.jsonutil import to_jsonable
from spm_console.safe_io import MB, load_json, write_text_atomic
from spm_console.store.plan_schema import (
    FORMAT,
    VERSION,
    extra_to_dict,
    plan_from_dict,
    record_to_dict,
    route_to_dict,
)

#: Largest plan file read (a plan at the 100 000-step limit takes about 20 MB).
MAX_PLAN_BYTES = 50 * MB
#: Profile sections a plan depends on.
PLAN_SECTIONS = ("geometry", "home", "links", "workspace", "servo")
#: Stored positions/velocities must match the re-simulated model to this (deg, deg/s).
CONSISTENCY_TOL = 1e-6


def plan_hash(profile: Profile) -> str:
    """SHA-256 of the profile sections a plan depends on."""
    return profile.section_digest(*PLAN_SECTIONS)


def plan_to_dict(plan: Plan) -> dict[str, Any]:
    """The JSON document of a plan (the documented keys first: the summary's figures, then
    the arrays)."""
    s = plan.summary()
    d: dict[str, Any] = {
        "format": FORMAT,
        "version": VERSION,
        **s.figures(),
        "reference_deg": plan.reference_deg,
        "position_deg": plan.position_deg,
        "velocity_degps": plan.velocity_degps,
        "region": plan.region.to_dict(),
        **({"route": route_to_dict(plan.route)} if plan.route is not None else {}),
        "model": plan.model.to_dict(),
        "profile_hash": s.profile_hash,
    }
    if plan.certificate is not None:
        d["n_minus_1_infeasible"] = record_to_dict(plan.certificate)
    d["extra"] = extra_to_dict(plan)
    return dict(to_jsonable(d))


def save_plan(plan: Plan, path: str | Path) -> None:
    """Write the plan atomically (temporary file + rename). Only a regular file (or nothing)
    may be replaced: a device, pipe or folder at ``path`` is refused (BadInputError)."""
    write_text_atomic(path, json.dumps(plan_to_dict(plan), indent=1) + "\n", BadInputError)


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
    if (m.method != sv.discretization or not math.isclose(m.p, sv.p, rel_tol=1e-12)
            or not math.isclose(m.zeta, sv.zeta, rel_tol=1e-12)
            or not math.isclose(m.delay_s, sv.delay_s, rel_tol=0, abs_tol=1e-12)):
        raise PlanMismatchError(
            f"{src}: servo model p = {m.p}, ζ = {m.zeta}, delay {m.delay_s} s, {m.method} but "
            f"the profile has p = {sv.p}, ζ = {sv.zeta}, delay {sv.delay_s} s, "
            f"{sv.discretization}")
    ref_model = servo_model_of(profile)
    A = np.asarray(m.A, float).reshape(2, 2)  # shapes checked by plan_from_dict
    B = np.asarray(m.B, float).reshape(2)
    if not (np.allclose(A, ref_model.A, rtol=0, atol=1e-9)
            and np.allclose(B, ref_model.B, rtol=0, atol=1e-9)):
        raise PlanMismatchError(f"{src}: model matrices A, B differ from the profile's servo model")
    # Comparisons are written "not (x <= tol)" so that a NaN (from values near 1e308 that
    # overflow in the simulation) is refused, never let through.
    x0 = np.column_stack([plan.position_deg[0], plan.velocity_degps[0]])
    with np.errstate(all="ignore"):
        xs = simulate(ref_model, x0, plan.reference_deg)
        err = float(np.max(np.abs(np.stack([xs[..., 0] - plan.position_deg,
                                            xs[..., 1] - plan.velocity_degps]))))
    if not err <= CONSISTENCY_TOL:
        raise PlanMismatchError(
            f"{src}: positions/velocities disagree with the servo model under the references by "
            f"{err:.3g} (corrupt or edited file)")
    if plan.kind in ("mvn", "mintime"):
        with np.errstate(all="ignore"):
            route = plan.regions
            viol = float(np.max(route.violation_deg(plan.position_deg, route.sample_mask(plan.N))))
            rest = max(float(np.max(np.abs(plan.velocity_degps[-1]))),
                       float(np.max(np.abs(plan.reference_deg[-1] - plan.position_deg[-1]))))
        if not viol <= 1e-6:
            raise PlanMismatchError(f"{src}: planned positions leave the plan's region"
                                    f"{'s' if route.count > 1 else ' P'} by {viol:.3g}°")
        if not rest <= 1e-6:
            raise PlanMismatchError(f"{src}: the plan does not end at rest on its final reference")


def load_plan(path: str | Path, profile: Profile) -> Plan:
    """Read a plan file and check it against ``profile``; raises PlanMismatchError.

    The file is read up to :data:`MAX_PLAN_BYTES` and its JSON nesting is capped, so a
    binary, huge or hostile file is refused with a message, never a traceback.
    """
    p = Path(path)
    d = load_json(p, "plan", MAX_PLAN_BYTES, PlanMismatchError)
    plan = plan_from_dict(d, str(p))
    check_plan(plan, profile, str(p))
    return plan
