"""``servo ping|read|torque`` (talk to a real or emulated bus, through the operator runtime:
the motion process owns the port, as for every motion) and ``emulate`` (serve one)."""

from __future__ import annotations

import argparse
import json
import threading
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

from spm_console.cli.common import (
    add_common,
    add_plant,
    emit,
    fault_text,
    info,
    integer,
    number,
    output_file,
    profile_of,
    to_jsonable,
)
from spm_console.cli.streams import stdout_guard
from spm_console.config.as_built import AsBuilt, load_as_built
from spm_console.config.schema import Profile
from spm_console.devices.emulator.bno055 import EmulatedBno055
from spm_console.devices.emulator.bus import start_emulator
from spm_console.devices.emulator.faults import parse_fault
from spm_console.devices.emulator.truth_log import MAX_TRUTH_LOG_S, TruthLog
from spm_console.devices.emulator.twin import TrueWrist, true_wrist
from spm_console.errors import BadInputError, BusError, ExitCode, OptionConflictError
from spm_console.input_rules import finite_number, theta_in_servo_limits
from spm_console.motion.servo_query import BusQuery, BusReport, check_ids
from spm_console.system.realtime import quick_gil_handoff
from spm_console.system.signals import install_stop_handler

#: Longest ``emulate --duration`` (one day; without --duration it runs until stopped).
MAX_EMULATE_S = 86_400.0


def register(sub: Any) -> None:
    s = sub.add_parser("servo", help="talk to the servo bus (ping, read, torque)")
    ssub = s.add_subparsers(dest="servo_command", metavar="ACTION", required=True)

    def port_opts(p: argparse.ArgumentParser) -> None:
        add_common(p)
        p.add_argument("--port", metavar="DEV",
                       help="serial device (default: the profile's bus.port)")
        p.add_argument("--ids", nargs="+", type=integer, metavar="ID",
                       help="servo ids (default: the profile's three joints)")

    p = ssub.add_parser("ping", help="ping each servo; list ids with their model numbers")
    port_opts(p)
    p.set_defaults(func=cmd_ping)

    r = ssub.add_parser("read", help="read positions (deg), torque and hardware errors, "
                                     "or one register by name")
    port_opts(r)
    r.add_argument("--register", metavar="NAME",
                   help="control-table register name, e.g. present_temperature")
    r.set_defaults(func=cmd_read)

    t = ssub.add_parser("torque", help="switch torque on or off")
    port_opts(t)
    t.add_argument("state", choices=["on", "off"])
    t.set_defaults(func=cmd_torque)

    e = sub.add_parser("emulate", help="serve an emulated MX-106 bus on a pseudo-terminal "
                                       "(or a socket) until SIGINT/SIGTERM")
    add_common(e)
    e.add_argument("--fault", action="append", default=[], type=fault_text,
                   metavar="KIND[@SECONDS]",
                   help="inject a fault, e.g. unplug@5, stall:2@1, drop:0.05, corrupt:0.02, "
                        "delay:0.03@1, hwerror:1@2 (repeatable)")
    e.add_argument("--initial", nargs=3, type=number, metavar=("T1", "T2", "T3"),
                   help="power-on joint angles, deg (default: the profile's home)")
    add_plant(e, when="")
    e.add_argument("--link", choices=("pty", "socket"), default="pty",
                   help="pty (default): a serial device any serial tool opens; socket: a "
                        "Unix-domain socket, port unix:PATH, which the spm-console commands "
                        "open (less exposed to a loaded machine's delays)")
    e.add_argument("--duration", type=number, metavar="S",
                   help=f"stop by itself after S seconds, 0 < S ≤ {MAX_EMULATE_S:g}")
    e.add_argument("--as-built", type=Path, metavar="FILE.toml",
                   help="with --plant physical: emulate the wrist as it was built (servo ids, "
                        "Drive Mode reverse bits, horn offsets, link arcs, base tilt, IMU "
                        "mount, payload), not as the profile describes it")
    e.add_argument("--jig", action="store_true",
                   help="with --plant physical: power on, torque off, held at the true home by "
                        "an operator's jig; the jig comes off at the first torque-on")
    e.add_argument("--imu", action="store_true",
                   help="with --plant physical: a BNO055 on the platform (UART mode) on a "
                        "pseudo-terminal of its own, fed by MuJoCo's accelerometer and gyroscope "
                        "(its port: imu_port in the first JSON line)")
    e.add_argument("--truth-log", type=Path, metavar="FILE.csv",
                   help="with --plant physical: write the true platform quaternion and joint "
                        f"angles at 100 Hz (at most {MAX_TRUTH_LOG_S / 3600:g} h; replaced if "
                        "it exists), for tests and benchmarks")
    e.set_defaults(func=cmd_emulate)


def _query(args: argparse.Namespace, q: BusQuery) -> BusReport:
    """Run ``q`` in the operator runtime: the motion process opens the port (as for every
    motion), answers, and is closed again."""
    from spm_console.services.session import Session

    profile = profile_of(args)
    if args.ids:  # checked before the port is opened
        check_ids(list(args.ids))
    port = args.port or profile.bus.port
    if not port:
        raise BusError("no serial port: pass --port DEV (the profile's bus.port is empty); "
                       "'spm-console emulate' serves an emulated bus and prints its port")
    session = Session(profile, port=port)
    try:
        session.connect(check=False)  # a silent servo is what these commands report
        report: BusReport = session.require_bus().query(q)
        return report
    finally:
        session.close()


def cmd_ping(args: argparse.Namespace) -> int:
    r = _query(args, BusQuery("ping", tuple(args.ids or ())))
    found = [asdict(f) for f in r.found]
    lines = [f"id {d['id']:3d}  model {d['model_number']}  firmware {d['firmware']}" for d in found]
    emit(args, {"port": r.port, "protocol": r.protocol, "servos": found,
                "missing": list(r.missing)}, "\n".join(lines) or "no servo answered")
    if r.missing:
        raise BusError("; ".join(r.missing))
    return int(ExitCode.OK)


def cmd_read(args: argparse.Namespace) -> int:
    if args.register:
        r = _query(args, BusQuery("register", tuple(args.ids or ()), args.register))
        values = dict(r.values)
        emit(args, {"register": args.register, "values": values},
             "\n".join(f"id {i:3d}  {args.register} = {v}" for i, v in values.items()))
        return int(ExitCode.OK)
    if args.ids:
        raise OptionConflictError("--ids needs --register (positions are per joint)")
    r = _query(args, BusQuery("joints"))
    joints = [asdict(j) for j in r.joints]
    human = "\n".join(
        f"joint {j['joint']} (id {j['id']}): θ = {j['theta_deg']:8.3f}°  ticks {j['ticks']:5d}"
        f"  torque {'on' if j['torque'] else 'off'}  hw error: {j['hardware_error_text']}"
        for j in joints)
    emit(args, {"theta_deg": [j["theta_deg"] for j in joints], "joints": joints}, human)
    return int(ExitCode.OK)


def cmd_torque(args: argparse.Namespace) -> int:
    on = args.state == "on"
    r = _query(args, BusQuery("torque", tuple(args.ids or ()), on=on))
    emit(args, {"ids": list(r.ids), "torque": on}, f"torque {args.state}: ids {list(r.ids)}")
    return int(ExitCode.OK)


def _truth(args: argparse.Namespace, profile: Profile) -> TrueWrist | None:
    """The wrist as built that ``--as-built``, ``--jig`` or ``--truth-log`` asks for (without
    --as-built: the profile's wrist, with the IMU and jig of a wrist as built); None when none
    of them is given."""
    wanted = [o for o, v in (("--as-built", args.as_built), ("--jig", args.jig),
                             ("--imu", args.imu), ("--truth-log", args.truth_log)) if v]
    if not wanted:
        return None
    if profile.plant.model != "physical":
        raise OptionConflictError(f"{', '.join(wanted)}: only with --plant physical (the "
                                  f"rigid-body wrist; this one is {profile.plant.model})")
    if args.jig and args.initial is not None:
        raise OptionConflictError("--jig holds the wrist at home: not with --initial")
    as_built = AsBuilt() if args.as_built is None else load_as_built(args.as_built)
    return true_wrist(profile, as_built, str(args.as_built or "as-built"))


def _truth_log(path: Path | None) -> TruthLog | None:
    if path is None:
        return None
    output_file(path, "--truth-log", (".csv",))
    try:
        return TruthLog(path)
    except OSError as exc:
        raise BadInputError(f"--truth-log {path}: {exc.strerror or exc}") from None


def cmd_emulate(args: argparse.Namespace) -> int:
    profile = profile_of(args)
    faults = [parse_fault(f) for f in args.fault]
    truth = _truth(args, profile)
    initial = None if args.initial is None else \
        [float(x) for x in theta_in_servo_limits(args.initial, "--initial", profile)]
    if args.duration is not None:
        finite_number(args.duration, "--duration", 0.0, MAX_EMULATE_S, lo_open=True, unit="s")
    stop = threading.Event()
    log = _truth_log(args.truth_log)
    imu: EmulatedBno055 | None = None
    try:
        em = start_emulator(profile, faults, record=False, initial_deg=initial, link=args.link,
                            truth=truth, jig=args.jig, truth_log=log)
        if args.imu:
            quick_gil_handoff()  # the servos' and the IMU's threads answer serial lines
            try:
                imu = EmulatedBno055(em.imu_truth, seed=profile.emulator.seed)
            except BaseException:
                em.stop()
                raise
    except BaseException:
        if log is not None:
            log.close()
        raise
    restore = install_stop_handler(lambda _sig: stop.set())
    try:
        head = {"port": em.port, "link": em.link, "protocol": em.protocol,
                "ids": [m.id for m in em.maps], "model_number": profile.bus.model_number,
                "faults": [str(f) for f in faults], "profile": profile.name,
                "as_built": args.as_built is not None, "jig": bool(args.jig),
                "imu_port": None if imu is None else imu.port,
                "truth_log": None if log is None else str(log.path)}
        stream = stdout_guard.out()
        stream.write(json.dumps(to_jsonable(head)) + "\n" if args.json else f"{em.port}\n")
        stream.flush()
        info(f"emulating {len(em.servos)} MX-106 (protocol {em.protocol}, ids {head['ids']}) "
             f"on {em.port}; stop with Ctrl-C")
        t_end = time.monotonic() + args.duration if args.duration else None
        while not stop.is_set() and em.running:
            stop.wait(0.2 if t_end is None else max(0.0, min(0.2, t_end - time.monotonic())))
            if t_end is not None and time.monotonic() >= t_end:
                break
    finally:
        if imu is not None:
            imu.stop()
        em.stop()
        restore()
    st = em.stats
    summary: dict[str, Any] = {
        "stopped": True, "instructions": st.instructions, "replies": st.replies,
        "dropped": st.dropped, "corrupted": st.corrupted, "delayed": st.delayed,
        "silenced": st.silenced, "faults_fired": st.faults_fired}
    if log is not None:
        summary["truth_log"] = {"path": str(log.path), "rows": log.rows, "full": log.full}
    if args.json:
        stdout_guard.out().write(json.dumps(summary) + "\n")
        stdout_guard.out().flush()
    else:
        info(f"stopped after {st.instructions} instructions, {st.replies} replies")
    return int(ExitCode.OK)
