"""``spm-console design sweep|show|profile``: choose the next wrist's geometry.

``sweep SPEC.toml --out DIR`` computes every design of the spec (on an embedded local Dask
cluster, or ``--scheduler tcp://HOST:PORT``), resumable; ``show DIR`` ranks the designs and
draws a Pareto plot; ``profile DIR K --out NEW.toml`` writes design K's profile.
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

from spm_console.cli.common import PLOT_SUFFIXES, add_force, emit, info, integer, output_file, output_folder
from spm_console.design.ranking import RANKED, best, check_metric, design_profile_text, pareto
from spm_console.design.spec import DEFAULT_MAX_DESIGNS, load_spec
from spm_console.design.sweep import allowed_cores, run_sweep
from spm_console.design.table import load_table, read_base_text
from spm_console.errors import BadInputError, ExitCode
from spm_console.safe_io import write_text_atomic

#: Most designs listed per figure by ``design show``.
MAX_TOP = 100
#: A progress line at least this often when stderr is not a terminal, s.
LOG_EVERY_S = 10.0


def register(sub: Any) -> None:
    p = sub.add_parser("design", help="design sweeps over SPM geometry parameters (Dask)")
    dsub = p.add_subparsers(dest="design_command", metavar="ACTION", required=True)
    s = dsub.add_parser("sweep", help="compute every design of a spec (resumes a stopped sweep)")
    s.add_argument("spec", type=Path, metavar="SPEC.toml", help="the sweep's specification")
    s.add_argument("--out", type=str, required=True, metavar="DIR",
                   help="folder of the sweep (created; the same folder resumes it)")
    s.add_argument("--scheduler", metavar="ADDRESS", default=None,
                   help="an existing Dask scheduler (tcp://HOST:PORT); default: a local "
                        "cluster on the allowed cores")
    s.add_argument("--workers", type=integer, default=None, metavar="N",
                   help="worker processes of the local cluster (default: one per allowed core; "
                        "0: in this process, without Dask)")
    s.add_argument("--max-designs", type=integer, default=None, metavar="N",
                   help="refuse a spec with more designs (default 100000)")
    s.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    s.set_defaults(func=cmd_sweep)
    sh = dsub.add_parser("show", help="the best designs per figure, and a Pareto plot")
    sh.add_argument("folder", type=Path, metavar="DIR")
    sh.add_argument("--top", type=integer, default=3, metavar="K",
                    help=f"designs per figure (1..{MAX_TOP}, default 3)")
    sh.add_argument("--metric", action="append", default=None, metavar="NAME",
                    help="rank by this figure only (repeatable)")
    sh.add_argument("--pareto", nargs=2, default=None, metavar=("X", "Y"),
                    help="the Pareto front of two figures (default tilt_cone_deg zeta_mean)")
    sh.add_argument("--plot", type=Path, default=None, metavar="FILE",
                    help="draw the Pareto plot (.png, .svg or .pdf)")
    sh.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    sh.set_defaults(func=cmd_show)
    pr = dsub.add_parser("profile", help="write one design's complete, validated profile")
    pr.add_argument("folder", type=Path, metavar="DIR")
    pr.add_argument("index", type=integer, metavar="K", help="the design's index in the table")
    pr.add_argument("--out", type=Path, required=True, metavar="NEW.toml")
    add_force(pr)
    pr.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    pr.set_defaults(func=cmd_profile)


def progress_printer(stream: TextIO) -> Callable[[Any], None]:
    """A progress bar on a terminal (designs done, rate, ETA); a line at least every
    :data:`LOG_EVERY_S` and at the end otherwise."""
    tty = stream.isatty()
    last = [0.0]

    def show(p: Any) -> None:
        eta = p.eta_s
        when = "ETA --" if eta is None else f"ETA {_duration(eta)}"
        text = (f"{p.done}/{p.total} designs · {p.rate_per_s * 60:.1f}/min · {when}")
        now = time.monotonic()
        if tty:
            width = 30
            full = int(width * p.done / max(p.total, 1))
            stream.write(f"\r[{'#' * full}{'.' * (width - full)}] {text}   ")
            if p.done >= p.total:
                stream.write("\n")
        elif now - last[0] >= LOG_EVERY_S or p.done >= p.total:
            stream.write(text + "\n")
            last[0] = now
        stream.flush()

    return show


def _duration(s: float) -> str:
    if s < 90:
        return f"{s:.0f} s"
    if s < 5400:
        return f"{s / 60:.0f} min"
    return f"{s / 3600:.1f} h"


def check_scheduler(address: str) -> None:
    """A Dask scheduler's address: ``tcp://HOST:PORT`` (or ``tls://``, or ``HOST:PORT``)."""
    m = re.fullmatch(r"(?:(tcp|tls)://)?([A-Za-z0-9.\-]+|\[[0-9A-Fa-f:.]+\]):([0-9]{1,5})", address)
    if m is None or not 1 <= int(m.group(3)) <= 65535:
        raise BadInputError(f"--scheduler {address!r}: expected tcp://HOST:PORT (or tls://HOST:PORT)")


def cmd_sweep(args: argparse.Namespace) -> int:
    if not str(args.out).strip():
        raise BadInputError("--out: give the sweep's folder")
    output_folder(args.out, "--out")
    if args.scheduler is not None:
        check_scheduler(args.scheduler)
    if args.workers is not None and not 0 <= args.workers <= 4 * allowed_cores():
        raise BadInputError(f"--workers must be within 0..{4 * allowed_cores()} "
                            f"(4 × the allowed cores; 0: in this process, without Dask), "
                            f"got {args.workers}")
    if args.workers is not None and args.scheduler is not None:
        raise BadInputError("--workers sizes the local cluster: not with --scheduler")
    spec = load_spec(args.spec, DEFAULT_MAX_DESIGNS if args.max_designs is None else args.max_designs)
    info(f"sweep of {spec.count} designs ({spec.sampling}: {', '.join(spec.names)}), grid "
         f"Δ = {spec.base.workspace.step_deg:g}°, into {args.out}")
    out = run_sweep(spec, Path(args.out), args.scheduler, args.workers, progress_printer(sys.stderr))
    rec = {"ok": True, "folder": str(out.folder), "table": str(out.table), "designs": out.total,
           "resumed": out.resumed, "computed": out.computed, "failed": out.failed,
           "internal_errors": out.internal_errors,
           "seconds": out.seconds, "workers": out.workers,
           "worker_peak_rss_mb": out.worker_peak_rss_mb}
    human = (f"{out.total} designs in {out.table}: {out.computed} computed now on "
             f"{out.workers} workers in {out.seconds:.1f} s, {out.resumed} done before; "
             f"{out.failed} could not be built (see their reason column)")
    if out.internal_errors:
        info(f"warning: {out.internal_errors} designs met an internal error (a bug: their reason "
             "says which; please report it). The same command runs them again.")
    emit(args, rec, human)
    return int(ExitCode.OK)


def cmd_show(args: argparse.Namespace) -> int:
    if not 1 <= args.top <= MAX_TOP:
        raise BadInputError(f"--top must be within 1..{MAX_TOP}, got {args.top}")
    output_file(args.plot, "--plot", PLOT_SUFFIXES)
    metrics = args.metric or list(RANKED)
    for m in metrics:
        check_metric(m, "--metric")
    x, y = args.pareto or ("tilt_cone_deg", "zeta_mean")
    if x == y:
        raise BadInputError(f"--pareto {x} {y}: give two different figures")
    info_, cols = load_table(args.folder)
    ranked = {m: best(cols, info_.names, m, args.top) for m in metrics}
    front = pareto(cols, x, y)
    if args.plot is not None:
        from spm_console.report.plot_pareto import plot_pareto

        plot_pareto(cols, x, y, front, args.plot, title=f"{args.folder.name}: {len(cols['index'])} designs")
    rec = {"ok": True, "folder": str(args.folder), "designs": info_.count,
           "done": len(cols["index"]), "built": int(sum(bool(v) for v in cols["ok"])),
           "parameters": list(info_.names),
           "best": {m: [{"index": r.index, "value": r.value, "params": r.params} for r in rs]
                    for m, rs in ranked.items()},
           "pareto": {"x": x, "y": y, "designs": [
               {"index": int(cols["index"][r]), x: cols[x][r], y: cols[y][r]} for r in front]},
           "plot": None if args.plot is None else str(args.plot)}
    lines = [f"{args.folder}: {rec['done']} of {info_.count} designs done, {rec['built']} built"]
    for m, rs in ranked.items():
        better = "higher" if RANKED[m] else "lower"
        lines.append(f"{m} ({better} is better):")
        lines += [f"  #{r.index}: {r.value:.4g}  " + ", ".join(f"{k} = {v:.4g}" for k, v in r.params.items())
                  for r in rs] or ["  (no design built)"]
    lines.append(f"Pareto front of {x} and {y}: " + (", ".join(
        f"#{cols['index'][r]}" for r in front) or "empty"))
    if args.plot is not None:
        lines.append(f"plot: {args.plot}")
    emit(args, rec, "\n".join(lines))
    return int(ExitCode.OK)


def cmd_profile(args: argparse.Namespace) -> int:
    output_file(args.out, "--out", (".toml",), replace=args.force)
    info_, cols = load_table(args.folder)
    text, prof = design_profile_text(args.folder, read_base_text(args.folder), info_.names, cols,
                                     args.index)
    write_text_atomic(args.out, text, BadInputError)
    emit(args, {"ok": True, "out": str(args.out), "index": args.index, "profile": prof.name,
                "geometry": prof.geometry.model_dump(), "links": prof.links.model_dump(
                    exclude={"segments"}), "sign_seed": list(prof.home.sign_seed)},
         f"design {args.index}'s profile written to {args.out} (validated; the workspace grid "
         f"is the base profile's)")
    return int(ExitCode.OK)
