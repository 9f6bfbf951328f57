"""``workspace build | show | check | region | verify``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

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
from spm_console.core.regions.choice import choose_region
from spm_console.core.workspace.build import check_theta
from spm_console.core.workspace.data import Workspace
from spm_console.core.workspace.verify import verify_cover, verify_region
from spm_console.errors import BadInputError, ExitCode
from spm_console.formatting import fmt_vec
from spm_console.input_rules import bounded_int, theta_in_grid
from spm_console.safe_io import write_text_atomic
from spm_console.store.workspace_cache import CacheInfo, load_or_build

#: Most samples ``workspace verify`` checks (about 5 minutes; memory stays bounded).
MAX_VERIFY_SAMPLES = 10_000_000


def register(sub: Any) -> None:
    p = sub.add_parser("workspace", help="workspace grid, feasible region P, checks")
    wsub = p.add_subparsers(dest="ws_command", metavar="ACTION", required=True)

    b = wsub.add_parser("build", help="build (or load) the workspace and its region P")
    _common(b)
    b.add_argument("--force", action="store_true", help="rebuild even if the cache matches")
    b.set_defaults(func=cmd_build)

    s = wsub.add_parser("show", help="counts and region P of the cached workspace")
    _common(s)
    s.add_argument("--plot", type=Path, metavar="FILE.png", help="save a Fig. 5-like picture")
    s.set_defaults(func=cmd_show)

    c = wsub.add_parser("check", help="is θ feasible (and inside P)? exit 6 if not feasible")
    _common(c)
    c.add_argument("--theta", nargs=3, type=number, required=True, metavar=("T1", "T2", "T3"),
                   help="motor angles, deg")
    c.set_defaults(func=cmd_check)

    r = wsub.add_parser("region", help="print P, or a region containing two configurations")
    _common(r)
    r.add_argument("--contain", nargs=6, type=number, metavar="DEG",
                   help="θa (3 values) then θb (3 values), deg")
    r.add_argument("--out", type=Path, metavar="FILE.json", help="also write {A, b} to a file")
    add_force(r)
    r.set_defaults(func=cmd_region)

    v = wsub.add_parser("verify", help="sample P uniformly and check every point exactly")
    _common(v)
    v.add_argument("--samples", type=integer, default=100_000,
                   help=f"number of samples, 1..{MAX_VERIFY_SAMPLES:,} (default 100,000)")
    v.add_argument("--seed", type=integer, default=0, help="random seed, 0..2³²−1")
    v.add_argument("--cover", action="store_true",
                   help="verify every region of the cover (--samples each), not only P")
    v.set_defaults(func=cmd_verify)


def _common(p: argparse.ArgumentParser) -> None:
    add_common(p)
    p.add_argument("--cache-dir", type=Path, default=None,
                   help="cache directory (default $SPM_CONSOLE_CACHE or ~/.cache/spm_console)")
    p.add_argument("--refined-cover", action="store_true",
                   help="the workspace whose region cover is refined near the boundary "
                        "(≥ 99 %% of the feasible nodes; a slower build, its own cache file)")


def _progress(stage: str, frac: float) -> None:
    sys.stderr.write(f"\rbuilding workspace: {stage:7s} {100 * frac:5.1f} %")
    if stage == "done":
        sys.stderr.write("\n")
    sys.stderr.flush()


def _load(args: argparse.Namespace, force: bool = False,
          profile: Profile | None = None) -> tuple[Workspace, CacheInfo]:
    profile = profile or profile_of(args)
    prog = _progress if sys.stderr.isatty() else None
    ws, ci = load_or_build(profile, args.cache_dir, force=force, progress=prog,
                           refined_cover=args.refined_cover or None)
    if not ci.hit:
        info(f"workspace built in {ci.build_seconds:.2f} s ({ci.rebuilt_because})")
    if ci.write_error:
        info(f"warning: {ci.write_error}")
    return ws, ci


def cover_record(ws: Workspace) -> dict[str, Any] | None:
    """The region cover in a record (None when the workspace has none)."""
    c = ws.cover
    if c is None:
        return None
    return {
        "regions": c.size, "covered": c.covered, "edges": c.edges.tolist(),
        "edge_radius_deg": c.edge_radius_deg.tolist(), "min_overlap_deg": c.min_overlap_deg,
        "connected": c.connected, "halfspaces": [r.halfspaces for r in c.regions],
        "seconds": c.seconds, "describe": c.describe(),
        "resolution_deg": c.resolution_deg, "refined_cells": c.refined_cells,
        "fine_nodes": c.fine_nodes, "refine_seconds": c.refine_seconds,
    }


def summary(ws: Workspace, ci: CacheInfo) -> dict[str, Any]:
    """The JSON record of a workspace."""
    return {
        "cover": cover_record(ws),
        **ws.counts(),
        "seconds": ws.seconds,
        "region_seconds": ws.region_seconds,
        "cache": {"path": str(ci.path), "hit": ci.hit, "rebuilt_because": ci.rebuilt_because,
                  "load_seconds": ci.load_seconds, "key": ci.key},
        "region": ws.region.to_dict(),
        "halfspaces": ws.region.halfspaces,
        "coverage": ws.coverage(),
        "grid": {"min_deg": ws.range_deg()[0], "max_deg": ws.range_deg()[1],
                 "step_deg": ws.step_deg, "zeta_min": ws.zeta_min,
                 "min_link_distance_mm": ws.min_distance_mm},
    }


def _human(rec: dict[str, Any]) -> str:
    c = rec["cache"]
    src = "cache hit" if c["hit"] else f"built ({c['rebuilt_because']})"
    return "\n".join([
        f"grid {rec['grid']['min_deg']:g}..{rec['grid']['max_deg']:g}° step "
        f"{rec['grid']['step_deg']:g}°: {rec['nodes']} nodes",
        f"feasible {rec['feasible']}, singular {rec['singular']}, colliding {rec['colliding']} "
        f"(unreached {rec['unreached']}, disconnected {rec['disconnected']})",
        f"region P: {rec['halfspaces']} half-spaces, covers {100 * rec['coverage']:.1f} % of "
        f"feasible nodes",
        *([rec["cover"]["describe"]] if rec["cover"] is not None else []),
        f"build {rec['seconds']:.2f} s (region {rec['region_seconds']:.2f} s"
        + (f", cover {rec['cover']['seconds']:.2f} s" if rec["cover"] is not None else "")
        + f"); {src}: {c['path']}",
    ])


def cmd_build(args: argparse.Namespace) -> int:
    ws, ci = _load(args, force=args.force)
    rec = summary(ws, ci)
    emit(args, rec, _human(rec))
    return int(ExitCode.OK)


def cmd_show(args: argparse.Namespace) -> int:
    output_file(args.plot, "--plot", PLOT_SUFFIXES)
    ws, ci = _load(args)
    rec = summary(ws, ci)
    if args.plot is not None:
        from spm_console.report.plot_workspace import plot_workspace

        try:
            plot_workspace(ws, args.plot)
        except OSError as exc:
            raise BadInputError(f"--plot {args.plot}: cannot write: {exc.strerror or exc}") from None
        rec["plot"] = str(args.plot)
        info(f"wrote {args.plot}")
    emit(args, rec, _human(rec))
    return int(ExitCode.OK)


def cmd_check(args: argparse.Namespace) -> int:
    profile = profile_of(args)
    theta = theta_in_grid(args.theta, "--theta", profile)  # O(1), before any FK work
    ws, _ = _load(args, profile=profile)
    c = check_theta(ws, theta)
    rec = {
        "theta_deg": c.theta_deg, "feasible": c.feasible, "in_region": c.in_region,
        "plannable": c.plannable, "verdict": c.verdict, "reason": c.reason, "zeta": c.zeta,
        "min_link_distance_mm": c.min_link_mm, "closest_pair": c.closest_pair,
        "in_range": c.in_range, "connected": c.connected,
        "region_slack_deg": c.region_slack_deg,
    }
    lines = [f"θ = {fmt_vec(theta, 2)} deg: {c.verdict}"]
    if c.zeta is not None:
        lines.append(f"ζ = {c.zeta:.3f}, closest links {c.min_link_mm:.1f} mm ({c.closest_pair})")
    if c.feasible and not c.in_region:
        lines.append("(`workspace region --contain` builds such a region for inspection)")
    emit(args, rec, "\n".join(lines))
    return int(ExitCode.OK if c.feasible else ExitCode.INFEASIBLE)


def cmd_region(args: argparse.Namespace) -> int:
    profile = profile_of(args)
    output_file(args.out, "--out", replace=args.force)
    if args.contain is not None:
        a = theta_in_grid(list(args.contain[:3]), "--contain θa", profile)
        b = theta_in_grid(list(args.contain[3:]), "--contain θb", profile)
    ws, _ = _load(args, profile=profile)
    if args.contain is None:
        region, cached = ws.region, True
        rec: dict[str, Any] = {}
        what = f"cached P: {region.halfspaces} half-spaces"
    else:
        choice = choose_region(ws, a, b)
        region = choice.region
        cached = choice.kind == "P"
        rec = {"theta_a_deg": a, "theta_b_deg": b, "kind": choice.kind,
               "resolution_deg": choice.resolution_deg}
        what = (f"cached P: {region.halfspaces} half-spaces" if cached
                else f"new region: {choice.describe()}")
    feas = ws.theta_deg()[ws.feasible]
    cov = float(region.contains(feas).mean()) if len(feas) else 0.0
    rec.update({"region": region.to_dict(), "halfspaces": region.halfspaces,
                "cached_region": cached, "coverage": cov})
    if args.out is not None:
        try:
            write_text_atomic(args.out, json.dumps(region.to_dict()) + "\n", BadInputError)
        except OSError as exc:
            raise BadInputError(f"--out {args.out}: cannot write: {exc.strerror or exc}") from None
    human = f"{what}, covers {100 * cov:.1f} % of feasible nodes"
    emit(args, rec, human)
    return int(ExitCode.OK)


def cmd_verify(args: argparse.Namespace) -> int:
    n = bounded_int(args.samples, "--samples", 1, MAX_VERIFY_SAMPLES)
    seed = bounded_int(args.seed, "--seed", 0, 2**32 - 1)
    ws, _ = _load(args)
    model, links = ws.exact_models()
    if args.cover:
        return _verify_cover(args, ws, n, seed)
    r = verify_region(ws, model, links, n=n, seed=seed)
    rec = {
        "samples": r.samples, "infeasible": r.infeasible,
        "fraction_infeasible": r.fraction_infeasible, "fk_failures": r.fk_failures,
        "singular": r.singular, "colliding": r.colliding, "min_zeta": r.min_zeta,
        "min_link_distance_mm": r.min_link_mm, "min_link_pair": r.min_link_pair,
        "worst_theta_deg": r.worst_theta_deg, "worst_violation": r.worst_violation,
        "seconds": r.seconds, "halfspaces": ws.region.halfspaces,
    }
    human = (f"{r.samples} samples in P: {r.infeasible} infeasible "
             f"({100 * r.fraction_infeasible:.3f} %); min ζ {r.min_zeta:.3f} "
             f"(ζ_min {ws.zeta_min:g}), min link distance {r.min_link_mm:.1f} mm "
             f"(2δ {ws.min_distance_mm:g} mm, {r.min_link_pair}); {r.seconds:.1f} s")
    emit(args, rec, human)
    return int(ExitCode.OK if r.infeasible == 0 else ExitCode.ASSERTION_FAILED)


def _verify_cover(args: argparse.Namespace, ws: Workspace, n: int, seed: int) -> int:
    if ws.cover is None:
        raise BadInputError("this workspace has no region cover to verify")
    model, links = ws.exact_models()
    rows = []
    lines = []
    bad = 0
    for k, (reg, r) in enumerate(zip(ws.cover.regions,
                                     verify_cover(ws, model, links, n=n, seed=seed),
                                     strict=True)):
        bad += r.infeasible
        rows.append({"region": k, "samples": r.samples, "infeasible": r.infeasible,
                     "min_zeta": r.min_zeta, "min_link_distance_mm": r.min_link_mm,
                     "seconds": r.seconds, "halfspaces": reg.halfspaces})
        lines.append(f"region {k}: {r.samples} samples, {r.infeasible} infeasible; min ζ "
                     f"{r.min_zeta:.3f}, min link distance {r.min_link_mm:.1f} mm")
    emit(args, {"regions": rows, "infeasible": bad}, "\n".join(lines))
    return int(ExitCode.OK if bad == 0 else ExitCode.ASSERTION_FAILED)
