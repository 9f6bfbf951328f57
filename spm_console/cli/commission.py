"""``commission``: find the wrist's servos, map them to legs with the IMU on the platform,
zero them on the home jig and write the profile of the wrist as built
(:mod:`spm_console.services.commissioning.stages`)."""

from __future__ import annotations

import argparse
import select
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from spm_console.cli.common import (
    add_common,
    add_force,
    emit,
    info,
    number,
    output_file,
    output_folder,
    profile_of,
)
from spm_console.config.plant import MAX_PAYLOAD_KG
from spm_console.errors import BadInputError, ExitCode, OptionConflictError
from spm_console.input_rules import finite_number
from spm_console.system.signals import stop_signals


def register(sub: Any) -> None:
    c = sub.add_parser("commission", help="find the servos, map them to legs (IMU), zero them "
                                          "(home jig) and write the profile of the wrist as built")
    add_common(c)
    c.add_argument("--port", metavar="DEV", help="the servo bus (default: the profile's "
                   "bus.port; 'spm-console emulate' prints an emulated one)")
    c.add_argument("--imu-port", metavar="DEV",
                   help="the BNO055 on the platform, UART mode (115200 baud); without it you "
                        "are asked on the terminal which leg each nudge moved, and which way "
                        "(and the IMU stage is skipped)")
    c.add_argument("--jig", action="store_true",
                   help="the wrist rests on its home jig, torque off: zero the servos there "
                        "(without it, the IMU zeroes them where the wrist rests: each leg "
                        "swings ±1.8° and the platform's rotations give its angles)")
    c.add_argument("--no-imu-fit", action="store_true",
                   help="after the zero, skip the IMU stage (poses across the region P, "
                        "the fit of horn offsets, IMU mounting and base tilt, its verification)")
    c.add_argument("--payload-kg", type=number, metavar="KG",
                   help="the payload's mass, weighed (0 < KG ≤ 2): with the IMU stage's first "
                        "moment m·c it places the payload's centre (m·c / m), written as "
                        "[plant] payload_kg so that the twin and the exports carry it")
    c.add_argument("--out", type=Path, metavar="FILE.toml",
                   help="where to write the commissioned profile (default: beside the "
                        "profile, NAME.commissioned-TIME.toml, never over a file)")
    c.add_argument("--logs", type=Path, metavar="DIR",
                   help="run log root (default $SPM_CONSOLE_LOGS or logs/): the "
                        "commissioning's folder, with its nudges and IMU readings")
    add_force(c)
    c.set_defaults(func=cmd_commission)


#: The options :func:`~spm_console.services.commissioning.run.options_problem` weighs.
_OPTIONS = "--port, --imu-port, --jig, --no-imu-fit, --payload-kg"


def cmd_commission(args: argparse.Namespace) -> int:
    from spm_console.services.client import EstopRelay
    from spm_console.services.commissioning.profile_out import commissioned_lines, kept_port
    from spm_console.services.commissioning.run import (
        CommissionRequest,
        options_problem,
        run_commissioning,
    )

    profile = profile_of(args)
    port = args.port or profile.bus.port
    if not port:
        raise BadInputError("no serial port: pass --port DEV (the profile's bus.port is empty); "
                            "'spm-console emulate' serves an emulated bus and prints its port")
    output_file(args.out, "--out", (".toml",), replace=args.force)
    output_folder(args.logs, "--logs")
    payload_kg = None
    if args.payload_kg is not None:
        payload_kg = finite_number(args.payload_kg, "--payload-kg", 0.0, MAX_PAYLOAD_KG,
                                   lo_open=True, unit="kg")
    why = options_problem(port, args.imu_port, args.jig, not args.no_imu_fit, payload_kg)
    if why:
        raise OptionConflictError(f"commission: {why} ({_OPTIONS})")
    req = CommissionRequest(port, args.imu_port, args.jig, not args.no_imu_fit, args.out,
                            args.logs, payload_kg)
    relay = EstopRelay("commission")

    def on_signal(sig: signal.Signals) -> None:
        """A stop signal is the E-stop: the nudge or move running stops, the wrist holds,
        the run log is closed (spm_console.services.commissioning.run)."""
        relay.estop(f"signal {sig.name}", by_signal=True)

    with stop_signals(on_signal):
        done = run_commissioning(profile, Path(args.profile), req, info, relay,
                                 None if args.imu_port else ask_on_terminal)
    result = done.result
    legs = [{"leg": m.leg, "id": m.id, "direction": m.direction, "source": m.source,
             "rotation_deg": m.rotation_deg, "cos": m.cos} for m in result.legs]
    data = {"protocol": result.discovery.protocol,
            "found": [{"id": f.id, "model_number": f.model_number, "firmware": f.firmware}
                      for f in result.discovery.found],
            "legs": legs, "jig_ticks": result.jig_ticks, "tick_offsets": result.tick_offsets,
            "zeroed": result.tick_offsets is not None, "profile_written": str(done.written),
            "zero_at_rest": None if result.rest_zero is None else {
                "theta_deg": list(result.rest_zero.fit.theta_deg),
                "theta_std_deg": list(result.rest_zero.fit.theta_std_deg),
                "imu_mount_rotvec_deg": list(result.rest_zero.fit.mount_rotvec_deg),
                "residual_rms_deg": result.rest_zero.fit.residual_rms_deg},
            "log_dir": str(done.log_dir), "bus_port_written": kept_port(port),
            "imu_fit": None if result.refinement is None else _fit_json(result.refinement),
            "payload_kg": result.profile.plant.payload_kg,
            "payload_centre_mm": (None if result.profile.plant.payload_centre_mm is None
                                  else list(result.profile.plant.payload_centre_mm))}
    human = "\n".join([*commissioned_lines(result, port), f"profile written: {done.written}",
                       f"run log: {done.log_dir}"])
    emit(args, data, human)
    return int(ExitCode.OK)


#: Unrecognised answers to one question before commissioning gives up.
MAX_TRIES = 5
#: Longest answer line read, characters.
MAX_ANSWER = 200


def ask_on_terminal(question: str, answers: Sequence[str]) -> str:
    """Ask on stderr, read the answer from stdin: one of ``answers`` (any case; a unique
    prefix will do). BadInputError when stdin closes, nobody answers within
    :data:`ANSWER_TIMEOUT_S` or :data:`MAX_TRIES` answers are not one of them."""
    from spm_console.services.commissioning.stages import ANSWER_TIMEOUT_S

    for _ in range(MAX_TRIES):
        sys.stderr.write(f"{question} [{'/'.join(answers)}]: ")
        sys.stderr.flush()
        ready, _, _ = select.select([sys.stdin], [], [], ANSWER_TIMEOUT_S)
        if not ready:
            raise BadInputError(f"commission: no answer within {ANSWER_TIMEOUT_S:g} s to "
                                f"{question!r}")
        line = sys.stdin.readline(MAX_ANSWER)
        if not line:
            raise BadInputError(f"commission: stdin closed before an answer to {question!r} "
                                "(without --imu-port the operator answers on the terminal)")
        said = line.strip().lower()
        picked = [a for a in answers if a == said] or [a for a in answers if said and
                                                        a.startswith(said)]
        if len(picked) == 1:
            return picked[0]
        sys.stderr.write(f"  answer one of: {', '.join(answers)}\n")
    raise BadInputError(f"commission: no valid answer to {question!r} in {MAX_TRIES} tries")


def _fit_json(r: Any) -> dict[str, Any]:
    """The IMU stage for ``--json``: each parameter with its standard error and status, the
    Jacobian's singular values, what the data leave undetermined, the residuals."""
    fit = r.fit
    return {
        "horn_beyond_jig_deg": list(r.horn_deg), "motion_s": r.motion_s,
        "poses_deg": [list(p) for p in r.poses_deg],
        "parameters": [{"name": p.name, "value_deg": p.value_deg, "std_deg": p.std_deg,
                        "std_expected_deg": p.std_expected_deg, "status": p.status}
                       for p in fit.parameters],
        "singular_values": list(fit.singular_values),
        "undetermined": list(fit.undetermined_named),
        "residual_rms_deg": fit.residual_rms_deg,
        "held_out_gravity_max_deg": r.verification.gravity_max_deg,
        "held_out_gravity_rms_deg": r.verification.gravity_rms_deg,
        "payload": None if r.payload is None else {
            "first_moment_kgmm": list(r.payload.fit.first_moment_kgm * 1e3),
            "first_moment_std_kgmm": list(r.payload.fit.first_moment_std_kgm * 1e3),
            "compliance_deg_per_nm": r.payload.fit.compliance_deg_per_nm,
            "compliance_std_deg_per_nm": r.payload.fit.compliance_std,
            "rest_offset_deg": r.payload.fit.friction_deg,
            "residual_rms_deg": r.payload.fit.residual_rms_deg,
            "held_out_rms_deg": r.payload.held_out_rms_deg,
            "singular_values": list(r.payload.fit.singular_values)},
    }
