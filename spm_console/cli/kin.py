"""``fk`` and ``ik`` commands."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from spm_console.cli.common import add_common, emit, info, number, profile_of
from spm_console.config.models import link_model_of, model_of
from spm_console.config.schema import Profile
from spm_console.core.kinematics.ik import ROUNDED_AXES_TOL, ik, ik_rpy, nearest_orientation
from spm_console.core.kinematics.modes import assembly_modes
from spm_console.errors import BadInputError, ExitCode, InfeasibleError, UnreachableError
from spm_console.formatting import fmt_residual, fmt_vec
from spm_console.input_rules import FK_THETA_LIMIT_DEG, finite_number, rpy_angles, theta_for_fk
from spm_console.numbers import numeric_rows
from spm_console.safe_io import MB, read_text
from spm_console.services.kin_record import FkGraphSource, fk_record, fk_result, fk_route

#: Largest ``fk --theta-file`` read, and most θ rows in it.
MAX_THETA_FILE_BYTES = 10 * MB
MAX_THETA_ROWS = 10_000


def register(sub: Any) -> None:
    p = sub.add_parser("fk", help="unique forward kinematics (home assembly mode)")
    add_common(p)
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--theta", nargs=3, type=number, metavar=("T1", "T2", "T3"), help="motor angles, deg")
    g.add_argument("--theta-file", type=Path, metavar="CSV", help="one θ (3 columns, deg) per row")
    p.add_argument("--from", dest="from_theta", nargs=3, type=number, metavar=("T1", "T2", "T3"),
                   help="continue from this known configuration (itself tracked from home)")
    p.add_argument("--all-modes", action="store_true", help="also list every assembly mode")
    p.add_argument("--cache-dir", type=Path, default=None,
                   help="workspace cache directory, used only when a straight path from home "
                        "crosses a singularity (default $SPM_CONSOLE_CACHE or ~/.cache/spm_console)")
    p.set_defaults(func=cmd_fk)

    q = sub.add_parser("ik", help="inverse kinematics in the home working modes")
    add_common(q)
    h = q.add_mutually_exclusive_group(required=True)
    h.add_argument("--v", nargs=9, type=number, metavar="V", help="v1x v1y v1z v2x … v3z")
    h.add_argument("--rpy", nargs=3, type=number, metavar=("R", "P", "Y"),
                   help="roll pitch yaw from home, deg: R = Rz(Y) Ry(P) Rx(R)")
    q.set_defaults(func=cmd_ik)


def _read_theta_file(path: Path) -> np.ndarray:
    text = read_text(path, "--theta-file", MAX_THETA_FILE_BYTES, BadInputError)
    rows = []
    for n, vals in numeric_rows(text, str(path), 3, "three angles in degrees"):
        if not all(abs(x) <= FK_THETA_LIMIT_DEG for x in vals):
            raise BadInputError(f"{path}:{n}: angles must lie in {-FK_THETA_LIMIT_DEG:g}.."
                                f"{FK_THETA_LIMIT_DEG:g}° (one turn either way), got {vals}")
        rows.append(vals)
        if len(rows) > MAX_THETA_ROWS:
            raise BadInputError(f"{path}: more than {MAX_THETA_ROWS:,} θ rows; split the file")
    if not rows:
        raise BadInputError(f"{path}: no θ rows")
    return np.asarray(rows)


def _row_text(theta_deg: np.ndarray, rec: dict[str, Any]) -> str:
    """One human line of ``fk --theta-file``."""
    if not rec["ok"]:
        return f"θ={fmt_vec(theta_deg, 2)}  {rec['reason']}"
    via = f" (around a singularity: {rec['path']['waypoints']} waypoints)" if rec["path"]["route"] == "graph" else ""
    return f"θ={fmt_vec(theta_deg, 2)}  n={fmt_vec(rec['n'])} ζ={rec['zeta']:.3f}{via}"


def cmd_fk(args: argparse.Namespace) -> int:
    profile = profile_of(args)
    model, links = model_of(profile), link_model_of(profile)
    graph = FkGraphSource(profile, model, args.cache_dir)  # loaded only if a straight path fails
    start = None
    if args.from_theta is not None:
        start = fk_route(profile, model, theta_for_fk(args.from_theta, "--from"), graph)
        if not start.ok or start.pose is None:
            raise UnreachableError(f"--from configuration: {start.reason}")
    if args.theta_file is not None:
        T = _read_theta_file(args.theta_file)
        fast = model.track_batch(np.radians(T), *((start.pose.theta, start.pose.R) if start and start.pose
                                                  else (None, None)))
        head = start.waypoints_deg if start else (tuple(float(x) for x in np.degrees(model.theta_home)),)
        results = [replace(r, waypoints_deg=(*head, tuple(float(x) for x in t)),
                           route=start.route if start else "straight")
                   if r.ok else fk_route(profile, model, t, graph, start) for t, r in zip(T, fast, strict=True)]
        # every record names its row (from 1) and θ, a refused one too
        recs = [{"row": k, "theta_deg": [float(x) for x in t], **fk_record(profile, model, links, r)}
                for k, (t, r) in enumerate(zip(T, results, strict=True), 1)]
        human = "\n".join(_row_text(t, rec) for t, rec in zip(T, recs, strict=True))
        emit(args, recs, human)  # a JSON list, one record per row
        return int(ExitCode.OK if all(r["ok"] for r in recs) else ExitCode.UNREACHABLE)
    theta = theta_for_fk(args.theta, "--theta")
    r = fk_route(profile, model, theta, graph, start)
    if not r.ok or r.pose is None:
        raise UnreachableError(f"θ = {fmt_vec(theta, 2)}°: {r.reason}")
    modes = tuple(assembly_modes(model, r.pose.theta, r.pose.R)) if args.all_modes else None
    rec = fk_result(profile, model, links, r, modes)
    lines = [
        f"θ        = {fmt_vec(theta, 2)} deg",
        *(f"v{i + 1}       = {fmt_vec(r.pose.v[i])}" for i in range(3)),
        f"n        = {fmt_vec(r.pose.n)}",
        f"ζ        = {r.pose.zeta:.4f}",
        f"residual {fmt_residual(r.pose.residual)}",
        f"closest links = {rec.min_link_distance_mm:.1f} mm ({rec.closest_pair})",
        "feasible" if rec.feasible else f"NOT feasible: {rec.reason}",
        "" if rec.path is None else rec.path.line(),
    ]
    if modes is not None:
        lines.append(f"{len(modes)} assembly modes:")
        for k, m in enumerate(modes, 1):
            tag = "  <- home-connected" if m.home_connected else ""
            lines.append(f"  {k}: n={fmt_vec(m.n)} ζ={m.zeta:.3f}{tag}")
    emit(args, rec.as_json(), "\n".join(lines))
    return int(ExitCode.OK)


def _within_servo_limits(profile: Profile, theta_deg: np.ndarray) -> None:
    """InfeasibleError (exit 6) naming every joint whose IK angle is beyond its servo limits."""
    bad = [f"joint {i + 1} θ{i + 1} = {float(theta_deg[i]):.3f}° outside its servo limits "
           f"{j.min_deg:g}..{j.max_deg:g}°"
           for i, j in enumerate(profile.bus.joints)
           if not j.min_deg - 1e-9 <= float(theta_deg[i]) <= j.max_deg + 1e-9]
    if bad:
        raise InfeasibleError(
            f"this orientation needs θ = {fmt_vec(theta_deg, 3)}°: " + "; ".join(bad)
            + f" (profile '{profile.name}'); it cannot be reached")


def cmd_ik(args: argparse.Namespace) -> int:
    profile = profile_of(args)
    model = model_of(profile)
    if args.v is not None:
        vals = np.asarray([finite_number(x, "--v: every value") for x in args.v]).reshape(3, 3)
        near, dev = nearest_orientation(model, vals)
        if dev <= ROUNDED_AXES_TOL:  # (axes as fk prints them, to four decimals, among them)
            if dev > 1e-9:
                info(f"note: --v lies {dev:.1e} from the platform's nearest orientation: "
                     "θ is that orientation's")
            vals = near
        res = ik(model, vals)
    else:
        res = ik_rpy(model, *np.radians(rpy_angles(args.rpy, "--rpy")))
    _within_servo_limits(profile, res.theta_deg)
    rec = {
        "theta_deg": res.theta_deg,
        "theta_other_mode_deg": np.degrees(res.both[:, 1]),
        "v": res.v,
    }
    emit(args, rec, f"θ = {fmt_vec(res.theta_deg, 3)} deg (home working modes)")
    return int(ExitCode.OK)
