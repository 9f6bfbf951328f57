"""``spm-console export urdf|mjcf --out FILE``: the profile's wrist for ROS and MuJoCo."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from spm_console.cli.common import add_common, add_force, emit, output_file, profile_of
from spm_console.errors import BadInputError, ExitCode
from spm_console.safe_io import write_text_atomic

SUFFIXES = {"urdf": (".urdf", ".xml"), "mjcf": (".xml", ".mjcf")}


def register(sub: Any) -> None:
    p = sub.add_parser("export", help="write the profile's wrist as URDF (ROS) or MJCF (MuJoCo)")
    p.add_argument("format", choices=("urdf", "mjcf"),
                   help="urdf: base, links and platform as a tree (leg 1 closed; the logs' "
                        "joint states place legs 2 and 3); mjcf: the closed chain with "
                        "equality constraints and the legs' δ capsules, as the physical "
                        "emulator loads it")
    add_common(p)
    p.add_argument("--out", type=Path, required=True, metavar="FILE",
                   help="file to write (.urdf or .xml; .xml or .mjcf)")
    add_force(p)
    p.set_defaults(func=cmd_export)


def cmd_export(args: argparse.Namespace) -> int:
    from spm_console.description.for_profile import robot_description

    output_file(args.out, "--out", SUFFIXES[args.format], replace=args.force)
    profile = profile_of(args)
    text = robot_description(profile, args.format)
    write_text_atomic(args.out, text, BadInputError)
    emit(args, {"ok": True, "format": args.format, "out": str(args.out), "profile": profile.name,
                "bytes": len(text.encode())},
         f"{args.format.upper()} of '{profile.name}' written to {args.out}")
    return int(ExitCode.OK)
