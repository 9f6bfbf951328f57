"""``follow``: the wrist tracks targets live, re-planned every servo period (issue 15).

* ``--targets FILE.csv``: rows ``t, theta1, theta2, theta3`` (s, deg), or ``t, roll, pitch,
  yaw`` (deg, relative to home, IK in the home working mode) with ``--rpy``; a header line and
  ``#`` comments are skipped. Each target holds from its time until the next; the run ends
  when the last one is reached and settled.
* ``--udp PORT``: a socket on 127.0.0.1 only, receiving JSON lines ``{"theta_deg": [..]}`` or
  ``{"rpy_deg": [..]}``; ``{"end": true}`` ends the run (settled on the last target). A
  deadman (``--deadman``, default 0.5 s) holds the wrist when no target arrives for that
  long; following resumes with the next target. See ``examples/follow_udp_client.py``.

Homes first unless ``--skip-homing REASON``; signals E-stop (exit 20). Degrees, seconds.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from spm_console.cli.common import integer, number, output_may_be_gone, profile_of
from spm_console.cli.follow_source import UdpTargets
from spm_console.cli.run import _bus_opts, _report, _request, report_preview, twin_of, with_progress
from spm_console.errors import BadInputError
from spm_console.input_rules import finite_number
from spm_console.services.oneshot import FollowOneShot, follow_once
from spm_console.services.preview import preview_follow
from spm_console.store.target_file import read_target_csv


def register(sub: Any) -> None:
    f = sub.add_parser("follow", help="track targets live (CSV file or UDP), re-planned every Ts")
    _bus_opts(f)
    src = f.add_mutually_exclusive_group(required=True)
    src.add_argument("--targets", type=Path, metavar="FILE.csv",
                     help="timed targets: t, theta1, theta2, theta3 (or t, roll, pitch, yaw "
                          "with --rpy)")
    src.add_argument("--udp", type=integer, metavar="PORT",
                     help='live targets: JSON lines {"theta_deg": [..]} or {"rpy_deg": [..]} '
                          "on 127.0.0.1:PORT")
    f.add_argument("--rpy", action="store_true",
                   help="the CSV holds roll, pitch, yaw relative to home (deg)")
    f.add_argument("--deadman", type=number, default=None, metavar="S",
                   help="live targets: hold when none arrives for S seconds (default 0.5)")
    f.add_argument("--skip-homing", metavar="REASON", default="",
                   help="follow without homing first; REASON is written to the run log")
    f.add_argument("--preview", action="store_true",
                   help="with --targets: do not move the wrist; follow them on its twin in "
                        "simulated time from where the wrist rests and print the predicted run "
                        "(exit code: the predicted run's)")
    f.set_defaults(func=cmd_follow)


def cmd_follow(args: argparse.Namespace) -> int:

    profile = profile_of(args)
    req = _request(args, profile)
    if args.preview:
        if args.udp is not None:
            raise BadInputError("--preview follows a timed target file (--targets): live "
                                "targets come in real time")
        timed = read_target_csv(profile, args.targets, args.rpy)
        pv = preview_follow(twin_of(args), timed, req, source=str(args.targets))
        if isinstance(pv, FollowOneShot):  # the twin's homing stopped
            assert pv.homing is not None
            return _report(args, pv.homing.execution, {"preview": True,
                                                       "stopped_during": "homing"})
        return report_preview(args, pv, {"targets": str(args.targets)})
    if args.udp is not None:
        if not 1 <= args.udp <= 65535:
            raise BadInputError(f"--udp: a port in 1..65535, got {args.udp}")
        if args.rpy:
            raise BadInputError("--rpy applies to --targets (a UDP message says rpy_deg itself)")
        deadman = 0.5 if args.deadman is None else finite_number(args.deadman, "--deadman", 0.0,
                                                                 60.0, lo_open=True)
        with UdpTargets(profile, args.udp) as udp, with_progress(args, req):
            out = follow_once(profile, req, None, deadman, udp.pump, source=f"udp:{args.udp}")
            extra: dict[str, Any] = {"udp": {"port": args.udp, **udp.counts()}}
    else:
        if args.deadman is not None:
            raise BadInputError("--deadman applies to --udp (timed targets never go silent)")
        timed = read_target_csv(profile, args.targets, args.rpy)
        with with_progress(args, req):
            out = follow_once(profile, req, timed, source=str(args.targets))
        extra = {"targets": str(args.targets), "rows": len(timed.t_s)}
    homing = out.homing
    extra["homing"] = ({"skipped": req.skip_homing} if homing is None else
                       {"outcome": homing.execution.outcome,
                        "log_dir": str(homing.execution.log_dir or "") or None})
    if out.follow is None:
        assert homing is not None
        extra["stopped_during"] = "homing"
        return _report(args, homing.execution, extra)
    st = out.follow.stats
    if st is not None:
        extra["follow"] = st.to_dict()
        if not args.json:  # the terminal may have closed (SIGHUP) or the pipe: the code stands
            with output_may_be_gone():
                sys.stdout.write(f"re-planned {st.solves} times: solve p99 {st.solve_ms_p99:.2f} "
                                 f"ms, max {st.solve_ms_max:.2f} ms; {st.misses} missed, "
                                 f"{st.refused} refused by the check, {st.clamped} periods with "
                                 f"the target projected into P, {st.deadman_trips} deadman "
                                 "holds\n")
    return _report(args, out.follow.execution, extra)
