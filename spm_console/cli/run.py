"""``home`` and ``execute``: move the wrist (real bus or ``--sim``), log the run.

Both go through the operator runtime (:mod:`spm_console.services.oneshot`): the servo loop in
the motion process, the emulated bus in its own. ``execute`` homes first unless
``--skip-homing REASON`` overrides it (the reason is logged).

``execute --preview`` moves nothing: the whole command runs on the wrist's twin in simulated
time (:mod:`spm_console.services.preview`); its exit code is the predicted run's (0 when it
completes), so ``execute --preview && execute`` moves only what the twin completed.

Exit codes: 0 done; a stop ends with its own code (20 E-stop, 21 tracking error,
22 communication lost, 23 servo hardware error, 24 left the region, 25 servo
limit); refusals before motion use the usual codes (4 bad input, 5 unreachable
pose, 9 plan mismatch, 10 bus error).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from spm_console.cli.common import (
    add_common,
    add_plant,
    console_plant,
    emit,
    fault_text,
    info,
    number,
    output_folder,
    output_may_be_gone,
    profile_of,
    with_plant,
)
from spm_console.cli.streams.progress import RunProgress, wanted
from spm_console.config.load import load_profile
from spm_console.config.schema import Profile
from spm_console.devices.emulator.faults import parse_fault
from spm_console.errors import BadInputError
from spm_console.formatting import fmt_vec
from spm_console.input_rules import theta_in_servo_limits
from spm_console.motion.segments import ExecutionResult
from spm_console.services.oneshot import RunRequest, execute_once, home_once
from spm_console.services.preview import Preview, preview_execute
from spm_console.services.session import Session
from spm_console.store.plan_file import load_plan
from spm_console.system.signals import raised_interrupt


def _bus_opts(p: argparse.ArgumentParser) -> None:
    add_common(p)
    g = p.add_mutually_exclusive_group()
    g.add_argument("--sim", action="store_true",
                   help="start an emulated servo bus and use it (reached over the profile's "
                        "emulator.link)")
    g.add_argument("--port", metavar="DEV",
                   help="serial device, or unix:PATH for a socket bus (default: the profile's "
                        "bus.port; empty = --sim)")
    p.add_argument("--fault", action="append", default=[], type=fault_text,
                   metavar="KIND[@SECONDS]",
                   help="with --sim: inject a fault, e.g. unplug@1.0, stall:2@0.5, drop:0.05, "
                        "corrupt:0.02, delay:0.03@1.0, hwerror:1@0.5 (repeatable; seconds "
                        "after the run starts)")
    p.add_argument("--sim-start", nargs=3, type=number, metavar=("T1", "T2", "T3"),
                   help="with --sim: power-on joint angles of the emulated servos, deg "
                        "(default: the profile's home)")
    add_plant(p)
    p.add_argument("--logs", metavar="DIR",
                   help="log root (default: $SPM_CONSOLE_LOGS or logs/)")
    p.add_argument("--quiet", action="store_true",
                   help="no progress display on stderr (shown only when it is a terminal and "
                        "without --json)")


def register(sub: Any) -> None:
    h = sub.add_parser("home", help="read the pose, check the assembly mode, move home slowly")
    _bus_opts(h)
    h.set_defaults(func=cmd_home)

    e = sub.add_parser("execute", help="stream a plan to the servos every Ts, with safe stops")
    _bus_opts(e)
    e.add_argument("--plan", required=True, type=Path, metavar="FILE", help="plan file (JSON)")
    e.add_argument("--no-approach", action="store_true",
                   help="refuse instead of moving to the plan's start first")
    e.add_argument("--skip-homing", metavar="REASON", default="",
                   help="execute without homing first (the wrist's pose is trusted as read); "
                        "REASON is written to the run log")
    e.add_argument("--preview", action="store_true",
                   help="do not move the wrist: run the whole command on its twin in simulated "
                        "time from where the wrist rests, and print the predicted run (exit "
                        "code: the predicted run's)")
    e.set_defaults(func=cmd_execute)


#: Longest ``--skip-homing`` reason, characters.
MAX_REASON = 200


def _skip_reason(text: str) -> str:
    """The operator's reason, one printable line of at most MAX_REASON characters."""
    reason = " ".join(text.split())
    if text and not reason:
        raise BadInputError("--skip-homing: give a reason (it is written to the run log)")
    if len(reason) > MAX_REASON or not reason.isprintable():
        raise BadInputError(f"--skip-homing: one printable line of at most {MAX_REASON} "
                            "characters, please")
    return reason


def _request(args: argparse.Namespace, profile: Profile) -> RunRequest:
    faults = [parse_fault(f) for f in args.fault]
    start = None if args.sim_start is None else \
        theta_in_servo_limits(args.sim_start, "--sim-start", profile)
    output_folder(args.logs, "--logs")
    skip = _skip_reason(getattr(args, "skip_homing", ""))
    return RunRequest(port=args.port, sim=args.sim, faults=faults, sim_start_deg=start,
                      approach=not getattr(args, "no_approach", False), skip_homing=skip,
                      log_root=args.logs, on_late_signal=_late_signal,
                      lost_signal=raised_interrupt)


def with_progress(args: argparse.Namespace, req: RunRequest, verifies: bool = False) -> RunProgress:
    """The command's progress display (inert unless stderr is a terminal, without --quiet
    and --json), fed by ``req``'s samples; ``verifies``: a plan is verified after connecting."""
    prog = RunProgress(wanted(sys.stderr, args.quiet, args.json))

    def connected(session: Session) -> None:
        prog.total_s = lambda: session.motion_total_s
        prog.phase("verifying" if verifies else "connected")

    req.on_connected, req.on_sample = connected, prog.on_sample
    return prog


def _late_signal(name: str) -> None:
    with output_may_be_gone():
        info(f"note: {name} arrived after the motion had ended: nothing to stop")


def _report(args: argparse.Namespace, res: ExecutionResult, extra: dict[str, Any]) -> int:
    st = res.stats
    data: dict[str, Any] = {
        "outcome": res.outcome, "exit_code": int(res.exit_code), "message": res.message,
        "log_dir": str(res.log_dir) if res.log_dir else None, "final_deg": res.final_deg,
        "stop": st.to_dict().get("stop"), "stats": st.to_dict(),
        "realtime": {"granted": res.realtime_granted, "detail": res.realtime}, **extra,
    }
    data["settle"] = None if res.settle is None else res.settle.to_dict()
    lines = [f"{res.outcome}: {res.message}"]
    if res.final_deg is not None:
        lines.append(f"final θ = {fmt_vec(res.final_deg, 2)} deg")
    if res.settle is not None and res.settle.text():
        lines.append(res.settle.text())
    if st.samples and st.jitter_ms is not None and st.bus_ms is not None:
        lines.append(
            f"{st.samples} cycles; measured vs model RMS {st.tracking_rms_deg:.3f}°, max "
            f"{st.tracking_max_deg:.3f}°; jitter p99 {st.jitter_ms.p99:.2f} ms; bus "
            f"{st.bus_ms.mean:.2f} ms/cycle; retries {st.comm_retries}, failed cycles "
            f"{st.comm_failed_cycles}")
    if st.model is not None:
        lines.append(st.model.text())
    if res.realtime:
        lines.append(f"servo loop: {res.realtime}")
    if res.log_dir:
        lines.append(f"log: {res.log_dir}")
    with output_may_be_gone():  # after SIGHUP the terminal is gone: the exit code still tells
        emit(args, data, "\n".join(lines))
        if not res.ok:
            info(f"stopped: {res.message}")
        if st.model is not None and st.model.exceeds:
            info("warning: the servo model looks wrong for this servo (model error above "
                 f"{st.model.bound_deg:.2f}°); identify it: spm-console identify --experiment "
                 "--out NEW.toml")
        if res.realtime and not res.realtime_granted:
            info(f"warning: no real-time scheduling for the servo loop ({res.realtime}); "
                 "timing may suffer under load")
    return int(res.exit_code)


def cmd_execute(args: argparse.Namespace) -> int:
    profile = profile_of(args)
    req = _request(args, profile)
    plan = load_plan(args.plan, profile)
    if args.preview:
        return report_preview(args, preview_execute(twin_of(args), plan, req,
                                                    source=str(args.plan)),
                              {"plan": str(args.plan)})
    with with_progress(args, req, verifies=True):
        out = execute_once(profile, plan, req, source=str(args.plan))
    homing = out.homing
    extra = {"plan": str(args.plan), "kind": plan.kind, "N": plan.N,
             "homing": ({"skipped": req.skip_homing} if homing is None else
                        {"outcome": homing.execution.outcome,
                         "log_dir": str(homing.execution.log_dir or "") or None})}
    if homing is not None and not homing.execution.ok:
        extra["stopped_during"] = "homing"
    return _report(args, out.execution, extra)


def cmd_home(args: argparse.Namespace) -> int:
    profile = profile_of(args)
    req = _request(args, profile)
    with with_progress(args, req):
        r = home_once(profile, req)
    pose = r.pose
    extra = {
        "start_deg": r.start_deg,
        "home_deg": list(profile.home.theta_deg),
        "pose": None if pose is None else {"theta_deg": pose.theta_deg, "v": pose.v,
                                           "n": pose.n, "zeta": pose.zeta},
    }
    return _report(args, r.execution, extra)


def twin_of(args: argparse.Namespace) -> Profile:
    """The profile's twin for a preview: ``--plant`` when given, the profile's ``[plant]
    model`` when it names one, else the physical wrist."""
    base = load_profile(args.profile)
    return with_plant(base, console_plant(base, args.plant))


def _num(x: float) -> float | None:
    return x if math.isfinite(x) else None


def report_preview(args: argparse.Namespace, pv: Preview, extra: dict[str, Any]) -> int:
    """Print the predicted run (``extra``: what the command adds to its JSON); its exit code."""
    ex = pv.run.execution
    st = ex.stats
    model = st.model
    homing = pv.run.homing
    data: dict[str, Any] = {
        "preview": True, "outcome": ex.outcome, "exit_code": int(ex.exit_code),
        "message": ex.message, "plant": pv.plant,
        "start_deg": pv.start_deg, "final_deg": ex.final_deg,
        "final_error_deg": pv.final_error_deg,
        "tracking_rms_per_joint_deg": list(st.tracking_rms_per_joint_deg),
        "tracking_max_per_joint_deg": None if model is None else list(model.max_per_joint_deg),
        "min_margin_deg": _num(pv.min_margin_deg), "min_link_mm": _num(pv.min_link_mm),
        "link_limit_mm": pv.link_limit_mm, "simulated_s": pv.simulated_s, "wall_s": pv.wall_s,
        "peak_current_a": pv.peak_current_a,
        "log_dir": str(ex.log_dir) if ex.log_dir else None,
        "homing": None if homing is None else {
            "outcome": homing.execution.outcome,
            "log_dir": str(homing.execution.log_dir or "") or None},
        "stats": st.to_dict(), **extra,
    }
    wrist = "the physical wrist" if pv.plant == "physical" else "ideal servos (eq. 27)"
    lines = [f"preview on the twin ({wrist}; {pv.simulated_s:.2f} s simulated in "
             f"{pv.wall_s:.2f} s): {ex.outcome}: {ex.message}"]
    if st.tracking_rms_per_joint_deg and model is not None:
        lines.append(f"predicted tracking of the servo model: RMS "
                     f"{fmt_vec(st.tracking_rms_per_joint_deg, 3)}°, max "
                     f"{fmt_vec(model.max_per_joint_deg, 3)}° per joint")
    if pv.final_error_deg is not None:
        lines.append(f"final error against the goal: {fmt_vec(pv.final_error_deg, 3)}°")
    if math.isfinite(pv.min_margin_deg):
        lines.append(f"closest to the edge of the certified set P′: {pv.min_margin_deg:.3f}° "
                     f"(L∞); closest links: {pv.min_link_mm:.1f} mm (2δ = "
                     f"{pv.link_limit_mm:.1f} mm)")
    if pv.peak_current_a is not None:
        lines.append(f"peak motor current: {fmt_vec(pv.peak_current_a, 2)} A per joint")
    lines.append("nothing moved on the wrist" + (f"; log: {ex.log_dir} (preview)"
                                                  if ex.log_dir else ""))
    with output_may_be_gone():
        emit(args, data, "\n".join(lines))
        if not ex.ok:
            info(f"the preview stopped: {ex.message}")
    return int(ex.exit_code)
