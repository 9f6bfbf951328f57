"""``servo ping|read|torque`` (talk to a real or emulated bus) and ``emulate`` (serve one)."""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from typing import Any

from spm_console.cli.common import (
    add_common,
    emit,
    finite_number,
    info,
    profile_of,
    theta_in_servo_limits,
    to_jsonable,
)
from spm_console.devices.base import CommError
from spm_console.devices.bus import DynamixelBus, open_bus
from spm_console.devices.emulator import start_emulator
from spm_console.devices.faults import parse_fault
from spm_console.errors import BadInputError, BusError, ExitCode
from spm_console.profile import Profile
from spm_console.run.signals import install_stop_handler

#: Longest ``emulate --duration`` (one day; without --duration it runs until stopped).
MAX_EMULATE_S = 86_400.0


def register(sub: Any) -> None:
    s = sub.add_parser("servo", help="talk to the servo bus (ping, read, torque)")
    ssub = s.add_subparsers(dest="servo_command", metavar="ACTION", required=True)

    def port_opts(p: argparse.ArgumentParser) -> None:
        add_common(p)
        p.add_argument("--port", metavar="DEV",
                       help="serial device (default: the profile's bus.port)")
        p.add_argument("--ids", nargs="+", type=int, metavar="ID",
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
                                       "until SIGINT/SIGTERM")
    add_common(e)
    e.add_argument("--fault", action="append", default=[], metavar="KIND[@SECONDS]",
                   help="inject a fault, e.g. unplug@5, stall:2@1, drop:0.05, corrupt:0.02, "
                        "delay:0.03@1, hwerror:1@2 (repeatable)")
    e.add_argument("--initial", nargs=3, type=float, metavar=("T1", "T2", "T3"),
                   help="power-on joint angles, deg (default: the profile's home)")
    e.add_argument("--duration", type=float, metavar="S",
                   help=f"stop by itself after S seconds, 0 < S ≤ {MAX_EMULATE_S:g}")
    e.set_defaults(func=cmd_emulate)


def _bus(args: argparse.Namespace, profile: Profile) -> DynamixelBus:
    if args.ids:  # checked before the port is opened
        _check_ids(list(args.ids))
    port = args.port or profile.bus.port
    if not port:
        raise BusError("no serial port: pass --port DEV (the profile's bus.port is empty); "
                       "'spm-console emulate' serves an emulated bus and prints its port")
    return open_bus(profile, port)


def _check_ids(ids: list[int]) -> list[int]:
    bad = [i for i in ids if not 0 <= i <= 252]
    if bad:
        raise BadInputError(f"--ids: servo ids are 0..252, got {bad[:10]}")
    if len(set(ids)) != len(ids):
        raise BadInputError("--ids: give each servo id at most once")
    return ids


def _ids(args: argparse.Namespace, bus: DynamixelBus) -> list[int]:
    return _check_ids(list(args.ids) if args.ids else list(bus.ids))


def cmd_ping(args: argparse.Namespace) -> int:
    profile = profile_of(args)
    with _bus(args, profile) as bus:
        ids = _ids(args, bus)
        found, problems = [], []
        for ident in ids:
            try:
                st = bus.ping(ident)
                found.append({"id": st.id, "model_number": st.model_number,
                              "firmware": st.firmware})
            except BusError as exc:
                problems.append(exc.message)
        lines = [f"id {d['id']:3d}  model {d['model_number']}  firmware {d['firmware']}"
                 for d in found]
        emit(args, {"port": bus.port, "protocol": bus.protocol, "servos": found,
                    "missing": problems}, "\n".join(lines) or "no servo answered")
    if problems:
        raise BusError("; ".join(problems))
    return int(ExitCode.OK)


def cmd_read(args: argparse.Namespace) -> int:
    profile = profile_of(args)
    with _bus(args, profile) as bus:
        ids = _ids(args, bus)
        try:
            if args.register:
                if args.register not in bus.table.registers:
                    names = ", ".join(sorted(bus.table.registers))
                    raise BadInputError(f"unknown register {args.register!r} on the "
                                        f"{bus.table.model}; known: {names}")
                values = {i: bus.read(i, args.register) for i in ids}
                emit(args, {"register": args.register, "values": values},
                     "\n".join(f"id {i:3d}  {args.register} = {v}" for i, v in values.items()))
                return int(ExitCode.OK)
            if args.ids:
                raise BadInputError("--ids needs --register (positions are per joint)")
            ticks = bus.read_ticks()
            theta = [m.to_deg(t) for m, t in zip(bus.maps, ticks, strict=True)]
            torque = bus.torque()
            hw = bus.hardware_errors()
        except CommError as exc:
            raise BusError(f"reading from {bus.port} failed: {exc}") from None
        joints = [
            {"joint": m.joint, "id": m.id, "ticks": t, "theta_deg": th, "torque": tq,
             "hardware_error": h, "hardware_error_text": bus.describe_hardware_error(h)}
            for m, t, th, tq, h in zip(bus.maps, ticks, theta, torque, hw, strict=True)
        ]
        human = "\n".join(
            f"joint {j['joint']} (id {j['id']}): θ = {j['theta_deg']:8.3f}°  ticks {j['ticks']:5d}"
            f"  torque {'on' if j['torque'] else 'off'}  hw error: {j['hardware_error_text']}"
            for j in joints)
        emit(args, {"theta_deg": theta, "joints": joints}, human)
    return int(ExitCode.OK)


def cmd_torque(args: argparse.Namespace) -> int:
    profile = profile_of(args)
    with _bus(args, profile) as bus:
        ids = _ids(args, bus)
        on = args.state == "on"
        try:
            if on:
                bus.hold()  # goal := present position first, so torque-on does not lunge
            bus.set_torque(on, ids)
        except CommError as exc:
            raise BusError(f"torque {args.state} on {bus.port} failed: {exc}") from None
        emit(args, {"ids": ids, "torque": on}, f"torque {args.state}: ids {ids}")
    return int(ExitCode.OK)


def cmd_emulate(args: argparse.Namespace) -> int:
    profile = profile_of(args)
    faults = [parse_fault(f) for f in args.fault]
    initial = None if args.initial is None else \
        [float(x) for x in theta_in_servo_limits(args.initial, "--initial", profile)]
    if args.duration is not None:
        finite_number(args.duration, "--duration", 0.0, MAX_EMULATE_S, lo_open=True, unit="s")
    stop = threading.Event()
    em = start_emulator(profile, faults, record=False, initial_deg=initial)
    restore = install_stop_handler(lambda _sig: stop.set())
    try:
        head = {"port": em.port, "protocol": em.protocol, "ids": [m.id for m in em.maps],
                "model_number": profile.bus.model_number, "faults": [str(f) for f in faults],
                "profile": profile.name}
        if args.json:
            sys.stdout.write(json.dumps(to_jsonable(head)) + "\n")
        else:
            sys.stdout.write(f"{em.port}\n")
        sys.stdout.flush()
        info(f"emulating {len(em.servos)} MX-106 (protocol {em.protocol}, ids {head['ids']}) "
             f"on {em.port}; stop with Ctrl-C")
        t_end = time.monotonic() + args.duration if args.duration else None
        while not stop.is_set() and em.running:
            stop.wait(0.2 if t_end is None else max(0.0, min(0.2, t_end - time.monotonic())))
            if t_end is not None and time.monotonic() >= t_end:
                break
    finally:
        em.stop()
        restore()
    st = em.stats
    summary = {"stopped": True, "instructions": st.instructions, "replies": st.replies,
               "dropped": st.dropped, "corrupted": st.corrupted, "delayed": st.delayed,
               "silenced": st.silenced, "faults_fired": st.faults_fired}
    if args.json:
        sys.stdout.write(json.dumps(summary) + "\n")
        sys.stdout.flush()
    else:
        info(f"stopped after {st.instructions} instructions, {st.replies} replies")
    return int(ExitCode.OK)
