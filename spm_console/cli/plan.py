"""``plan mvn``, ``plan mintime`` and ``plan show`` commands."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, Literal

from spm_console.cli.common import (
    PLOT_SUFFIXES,
    add_common,
    add_force,
    emit,
    info,
    integer,
    number,
    output_file,
    profile_of,
)
from spm_console.config.schema import Profile
from spm_console.core.bounds import MAX_INSTANTS, N_MAX
from spm_console.core.plan import Plan, PlanSummary
from spm_console.core.polytope.region import Region
from spm_console.core.workspace.data import Workspace
from spm_console.errors import BadInputError, ExitCode, PlanRefusedError
from spm_console.formatting import fmt_vec
from spm_console.input_rules import (
    INTERSAMPLE,
    INTERSAMPLE_MAX,
    STEPS,
    STEPS_MIN,
    count_in,
    theta_in_grid,
    theta_in_servo_limits,
    vmax_arg,
)
from spm_console.motion.plan_check import verify_plan
from spm_console.report.plot_plan import plot_plan
from spm_console.safe_io import load_json
from spm_console.services.plan_request import PlanRequest, plan_motion, precheck
from spm_console.store.plan_file import MAX_PLAN_BYTES, load_plan, plan_to_dict, save_plan
from spm_console.store.plan_schema import record_to_dict, region_of
from spm_console.store.workspace_cache import load_or_build


def register(sub: Any) -> None:
    p = sub.add_parser("plan", help="optimal servo references: MVN (30), minimum time (31)")
    psub = p.add_subparsers(dest="plan_command", metavar="ACTION", required=True)

    m = psub.add_parser("mvn", help="minimum-velocity-norm references in N steps")
    _problem_args(m)
    m.add_argument("--steps", type=integer, default=150, metavar="N",
                   help=f"intervals N, {STEPS_MIN}..{N_MAX} (default 150)")
    m.add_argument("--vmax", type=number, default=None, metavar="V",
                   help="speed bound at the samples, deg/s, at most the profile's "
                   "limits.vmax_degps (default: that limit, which the executor enforces)")
    m.set_defaults(func=cmd_mvn)

    t = psub.add_parser("mintime", help="minimum-time references under a speed bound")
    _problem_args(t)
    t.add_argument("--vmax", type=number, default=None, metavar="V",
                   help="speed bound, deg/s, in (0, the profile's limits.vmax_degps] "
                   "(default: that limit)")
    t.set_defaults(func=cmd_mintime)

    s = psub.add_parser("show", help="check a plan file against the profile and summarize it")
    add_common(s)
    s.add_argument("file", type=Path, metavar="FILE")
    s.add_argument("--plot", type=Path, metavar="FILE.png", help="save a Figs. 7–10-like plot")
    s.set_defaults(func=cmd_show)


def _problem_args(p: argparse.ArgumentParser) -> None:
    add_common(p)
    p.add_argument("--start", nargs=3, type=number, required=True, metavar=("T1", "T2", "T3"),
                   help="start motor angles, deg")
    p.add_argument("--goal", nargs=3, type=number, required=True, metavar=("T1", "T2", "T3"),
                   help="goal motor angles, deg")
    p.add_argument("--intersample", type=integer, default=1, metavar="K",
                   help="also enforce speed and region at K−1 instants inside each interval "
                   f"(1..{INTERSAMPLE_MAX}, N·K ≤ {MAX_INSTANTS:,})")
    p.add_argument("--region", type=Path, default=None, metavar="FILE.json",
                   help="region {A, b} (θ in deg) instead of the workspace's P")
    p.add_argument("--cache-dir", type=Path, default=None, help="workspace cache directory")
    p.add_argument("--free-first", action="store_true",
                   help="let θ*(0) move (the paper's (30b) holds θ*(0) = θ(0))")
    p.add_argument("--no-ref-limits", action="store_true",
                   help="do not bound the references by the servo limits of the profile")
    p.add_argument("--out", type=Path, default=None, metavar="FILE", help="write the plan (JSON)")
    add_force(p)
    p.add_argument("--plot", type=Path, default=None, metavar="FILE.png", help="save a plot")


def _region_file(path: Path) -> Region:
    d = load_json(path, "--region", MAX_PLAN_BYTES, BadInputError)
    if isinstance(d, dict) and "region" in d and isinstance(d["region"], dict):
        d = d["region"]  # a plan file or a `workspace show --json` record
    return region_of(d, f"--region {path}: region", BadInputError)


def _workspace(args: argparse.Namespace, profile: Profile) -> Workspace:

    ws, ci = load_or_build(profile, getattr(args, "cache_dir", None))
    if not ci.hit:
        info(f"workspace built in {ci.build_seconds:.1f} s ({ci.rebuilt_because})")
    return ws


def _request(args: argparse.Namespace, profile: Profile, method: Literal["mvn", "mintime"],
             n: int, vmax: float | None) -> PlanRequest:
    """The options as the runtime's plan request (input bounds checked here, in O(1))."""
    k = count_in(args.intersample, "--intersample", INTERSAMPLE)
    output_file(args.out, "--out", replace=args.force)
    output_file(args.plot, "--plot", PLOT_SUFFIXES)
    if not args.no_ref_limits:
        theta_in_servo_limits(args.start, "--start", profile)
        theta_in_servo_limits(args.goal, "--goal", profile)
    s = theta_in_grid(args.start, "--start", profile)
    g = theta_in_grid(args.goal, "--goal", profile)
    region = None if args.region is None else _region_file(args.region)
    return PlanRequest(method, s, g, n, vmax, intersample=k, hold_first=not args.free_first,
                       reference_limits=not args.no_ref_limits, region=region,
                       region_source=f"the region of file {args.region}")


def summary(s: PlanSummary, out: Path | None, source: str,
            region_kind: str | None = None) -> dict[str, Any]:
    """The JSON record of a solved plan."""
    rec = s.figures()
    rec.update({"out": str(out) if out else None, "region": source, "region_kind": region_kind,
                "halfspaces": s.halfspaces,
                "route": None if s.route is None else {
                    "regions": list(s.route.labels), "switch_samples": list(s.route.switch),
                    "halfspaces": [r.halfspaces for r in s.route.regions]},
                "check": None if s.check is None else s.check.to_dict(),
                "solver": s.solver, "start_deg": s.start_deg, "goal_deg": s.goal_deg})
    if s.certificate is not None:
        rec["n_minus_1_infeasible"] = record_to_dict(s.certificate)
    return rec


def _human(s: PlanSummary, out: Path | None, source: str) -> str:
    c = s.check
    nan = float("nan")
    lines = [
        f"{s.kind}: N = {s.N} ({s.duration_s:.2f} s), cost {s.cost:.6g} (deg/s)², "
        f"{s.qp_count} QP(s), {1e3 * s.solve_seconds:.1f} ms",
        f"region: {source}",
        f"at the samples: max |θ̇| {c.max_speed_samples_degps if c else nan:.3f} deg/s, "
        f"region violation {(c.region_violation_deg if c else nan) + 0.0:.2e} deg",  # no −0
        f"between samples: max |θ̇| {c.max_speed_between_degps if c else nan:.3f} deg/s, "
        f"region violation {(c.region_violation_between_deg if c else nan) + 0.0:.3g} deg",
    ]
    if s.certificate is not None:
        lines.append(s.certificate.describe())
    if out:
        lines.append(f"written to {out}")
    return "\n".join(lines)


def _finish(args: argparse.Namespace, profile: Profile, req: PlanRequest) -> int:

    precheck(profile, req)  # a refusal never pays for the workspace
    planned = plan_motion(profile, _workspace(args, profile), req)
    plan, source = planned.plan, planned.describe_region()
    if args.out is not None:
        try:
            save_plan(plan, args.out)
        except OSError as exc:
            raise BadInputError(f"--out {args.out}: cannot write: {exc.strerror or exc}") from None
    if args.plot is not None:
        _plot(plan, args.plot)
    s = plan.summary()
    emit(args, summary(s, args.out, source, planned.region_kind), _human(s, args.out, source))
    return int(ExitCode.OK)


def _plot(plan: Plan, path: Path) -> None:

    try:
        plot_plan(plan, path)
    except OSError as exc:
        raise BadInputError(f"--plot {path}: cannot write: {exc.strerror or exc}") from None


def cmd_mvn(args: argparse.Namespace) -> int:
    profile = profile_of(args)
    n = count_in(args.steps, "--steps", STEPS)
    vmax = vmax_arg(args.vmax, profile, default_to_profile=True)
    k = count_in(args.intersample, "--intersample", INTERSAMPLE)
    if n * k > MAX_INSTANTS:
        raise BadInputError(f"--steps × --intersample = {n} × {k} is above {MAX_INSTANTS:,} "
                            "constrained instants; use fewer steps or a smaller K")
    return _finish(args, profile, _request(args, profile, "mvn", n, vmax))


def cmd_mintime(args: argparse.Namespace) -> int:
    profile = profile_of(args)
    vmax = vmax_arg(args.vmax, profile, default_to_profile=True)
    return _finish(args, profile, _request(args, profile, "mintime", 2, vmax))


def cmd_show(args: argparse.Namespace) -> int:
    profile = profile_of(args)
    output_file(args.plot, "--plot", PLOT_SUFFIXES)
    plan = load_plan(args.file, profile)
    if args.plot is not None:
        _plot(plan, args.plot)

    # what the runtime will decide (the figures above the verdict are the file's own claims)
    try:
        check = verify_plan(profile, _workspace(args, profile), plan)
        verdict = (f"runtime verification: passes ({check.points} points of the motion checked, "
                   f"max model speed {check.max_speed_degps:.1f} deg/s)")
        refused = None
    except PlanRefusedError as exc:
        verdict, refused = f"runtime verification: REFUSED — {exc.message}", exc
    d = plan_to_dict(plan) | {"verified": refused is None,
                              "refused": None if refused is None else refused.message}
    s = plan.summary()
    human = _human(s, None, s.stored_region()) + (
        f"\nstart {fmt_vec(s.start_deg, 2)} deg → goal {fmt_vec(s.goal_deg, 2)} deg\n{verdict}")
    emit(args, d, human)
    return int(ExitCode.OK if refused is None else refused.exit_code)
