"""``logs`` (list runs), ``logs show RUN [--plot FILE.png]`` and ``logs export --mcap RUN``."""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from spm_console.cli.common import add_common, add_force, emit, info, output_file, profile_of
from spm_console.errors import BadInputError, ExitCode
from spm_console.motion.logs.bag import METADATA_NAME
from spm_console.motion.logs.profile_record import same_profile
from spm_console.motion.logs.runlog import list_runs, load_run, resolve_run


def register(sub: Any) -> None:
    p = sub.add_parser("logs", help="list run logs, or show one (with a plot)")
    add_common(p)
    p.add_argument("--logs", metavar="DIR", help="log root (default: $SPM_CONSOLE_LOGS or logs/)")
    lsub = p.add_subparsers(dest="logs_command", metavar="ACTION")
    s = lsub.add_parser("show", help="summary of one run; --plot draws it (paper Figs. 7-10)")
    # same options after 'show' too; SUPPRESS keeps values given before 'show'
    s.add_argument("--profile", default=argparse.SUPPRESS, help=argparse.SUPPRESS)
    s.add_argument("--json", action="store_true", default=argparse.SUPPRESS,
                   help="print one JSON object on stdout")
    s.add_argument("--logs", metavar="DIR", default=argparse.SUPPRESS,
                   help="log root (default: $SPM_CONSOLE_LOGS or logs/)")
    s.add_argument("run", metavar="RUN", help="run folder name or path, or 'last'")
    s.add_argument("--plot", type=Path, metavar="FILE.png", help="write the figure here")
    s.set_defaults(func=cmd_show)
    e = lsub.add_parser("export", help="write a run as MCAP with ROS 2 messages (Foxglove, "
                                       "PlotJuggler) and its folder's metadata.yaml (a rosbag2 "
                                       "bag: ros2 bag info/play RUN): runs logged before MCAP "
                                       "was written beside the CSV, or whose MCAP was deferred")
    e.add_argument("--profile", default=argparse.SUPPRESS,
                   help="the profile the run was logged with (its name must match; another "
                        "version of it is noted on stderr)")
    e.add_argument("--json", action="store_true", default=argparse.SUPPRESS,
                   help="print one JSON object on stdout")
    e.add_argument("--logs", metavar="DIR", default=argparse.SUPPRESS,
                   help="log root (default: $SPM_CONSOLE_LOGS or logs/)")
    e.add_argument("--mcap", action="store_true", required=True, help="MCAP (the one format)")
    e.add_argument("run", metavar="RUN", help="run folder name or path, or 'last'")
    e.add_argument("--out", type=Path, metavar="FILE.mcap",
                   help="file to write, the MCAP alone (default: run.mcap and metadata.yaml in "
                        "the run's folder, which make it a rosbag2 bag)")
    add_force(e)
    e.set_defaults(func=cmd_export)
    p.set_defaults(func=cmd_list)


def cmd_list(args: argparse.Namespace) -> int:
    runs = list_runs(args.logs)
    rows = []
    for r in runs:
        m = r.meta
        rows.append({"run": r.name, "path": str(r.path), "kind": m.get("kind"),
                     "start_time": m.get("start_time"), "outcome": m.get("outcome"),
                     "exit_code": m.get("exit_code"), "samples": m.get("samples"),
                     "message": m.get("message", "")})
    human = "\n".join(
        f"{d['run']:34} {d['kind'] or '?':8} {d['outcome'] or '?':10} "
        f"{'' if d['exit_code'] is None else d['exit_code']:>3}  {str(d['message'] or '')[:70]}"
        for d in rows) or "no runs logged yet"
    emit(args, {"runs": rows}, human)
    return int(ExitCode.OK)


def cmd_show(args: argparse.Namespace) -> int:
    run = load_run(args.run, args.logs)
    m = run.meta
    counts = Counter(e.get("event", "?") for e in run.events)
    faults = [e for e in run.events if e.get("event") in ("fault", "stop", "refused")]
    data: dict[str, Any] = {
        "run": run.path.name, "path": str(run.path), "meta": m, "rows": run.rows,
        "truncated": run.truncated, "events": dict(counts), "faults": faults,
    }
    prof = m.get("profile")
    prof = prof if isinstance(prof, dict) else {}
    lines = [
        f"run {run.path.name}: {m.get('kind')} — {m.get('outcome')} "
        f"(exit {m.get('exit_code')}) {m.get('message', '')}",
        f"profile {prof.get('name')} ({str(prof.get('hash'))[:12]}…),"
        f" started {m.get('start_time')}",
        f"{run.rows} samples{' (last line truncated)' if run.truncated else ''}; events: "
        + (", ".join(f"{k} {v}" for k, v in counts.items()) or "none"),
    ]
    lines += [f"  t={e.get('t', 0):.3f} s {e.get('event')}: {e.get('message', e.get('kind', ''))}"
              for e in faults]
    if run.rows:
        ok = np.all(np.isfinite(run.vec("meas")), axis=1)
        err = (run.vec("meas") - run.vec("pred"))[ok]
        if err.size:
            rms = float(np.sqrt(np.mean(err**2)))
            data["tracking_rms_deg"] = rms
            lines.append(f"measured vs model: RMS {rms:.3f}°, max {np.abs(err).max():.3f}°")
    if args.plot is not None:
        if args.plot.suffix.lower() not in (".png", ".svg", ".pdf"):
            raise BadInputError(f"--plot {args.plot}: use a .png, .svg or .pdf file name")
        if run.rows:
            from spm_console.report.plot_run import plot_run

            plot_run(run, args.plot)
            data["plot"] = str(args.plot)
            lines.append(f"plot: {args.plot}")
        else:  # a commissioning's or a refused run's: its events are the record
            data["plot"] = None
            lines.append(f"plot: none written to {args.plot}: the run has no samples to draw")
    emit(args, data, "\n".join(lines))
    return int(ExitCode.OK)


def cmd_export(args: argparse.Namespace) -> int:
    from spm_console.motion.logs.mcap_log import LIMIT_SLACK_DEG, MCAP_NAME, write_run_mcap

    output_file(args.out, "--out", (".mcap",), replace=args.force)
    run_dir = resolve_run(args.run, args.logs)
    profile = profile_of(args)
    logged = load_run(run_dir).meta.get("profile", {})
    logged = logged if isinstance(logged, dict) else {}
    if logged.get("name") != profile.name:
        raise BadInputError(f"{run_dir.name} was logged with profile '{logged.get('name')}', not "
                            f"'{profile.name}' ({args.profile}): give the run's own profile with "
                            "--profile, its wrist draws the run")
    same = same_profile(logged, profile)
    if not same:  # the same prototype, its profile edited since (or a newer version's keys)
        info(f"note: {run_dir.name} was logged with another version of '{profile.name}' (digest "
             f"{str(logged.get('hash'))[:12]}…, now {profile.digest()[:12]}…): its joints are "
             f"drawn with {args.profile} as it is now")
    try:
        done = write_run_mcap(run_dir, profile, args.out)
    except OSError as exc:  # a folder this process cannot write, a full disk
        raise BadInputError(f"--out {args.out or run_dir / MCAP_NAME}: cannot write: "
                            f"{exc.strerror or exc}") from None
    out = done.path
    if done.first_beyond is not None:
        info(f"note: {done.beyond_limits} sample(s) of {run_dir.name}/samples.csv (the first: "
             f"sample {done.first_beyond}) measure a θ more than {LIMIT_SLACK_DEG:g}° beyond "
             f"the servo limits of '{profile.name}', no pose of this wrist: their /joint_states, "
             "/spm/platform and /tf are left out")
    meta = out.parent / METADATA_NAME if out == run_dir / MCAP_NAME else None
    emit(args, {"ok": True, "run": run_dir.name, "mcap": str(out), "bytes": out.stat().st_size,
                "bag_metadata": None if meta is None else str(meta),
                "profile_digest_matches": same, "samples_beyond_limits": done.beyond_limits,
                "first_beyond_limits": done.first_beyond},
         f"{run_dir.name}: MCAP written to {out}"
         + ("" if meta is None else f"; {meta.name} beside it: the folder is a ROS 2 bag"))
    return int(ExitCode.OK)
