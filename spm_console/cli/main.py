"""Entry point of ``spm-console``: one parser, one mapping from error to exit code."""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from spm_console import __version__
from spm_console.errors import ExitCode, SpmError

#: Command modules; each defines ``register(subparsers)`` and sets ``func`` on its parsers.
COMMAND_MODULES = [
    "spm_console.cli.kin",
    "spm_console.cli.servo",
    "spm_console.cli.workspace",
    "spm_console.cli.plan",
    "spm_console.cli.tui",
    "spm_console.cli.script",
    "spm_console.cli.run",
    "spm_console.cli.logs",
    "spm_console.cli.reproduce",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="spm-console",
        description="Operator console for 3-DOF spherical parallel manipulators "
        "(degrees, mm, seconds at every interface).",
    )
    parser.add_argument("--version", action="version", version=f"spm-console {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse: usage errors exit 2, --help exits 0
        return int(exc.code or 0)
    if not getattr(args, "func", None):
        parser.print_help(sys.stderr)
        return int(ExitCode.USAGE)
    try:
        return int(args.func(args))
    except SpmError as exc:
        sys.stderr.write(f"error: {exc.message}\n")
        return int(exc.exit_code)
    except KeyboardInterrupt:
        sys.stderr.write("interrupted\n")
        return int(ExitCode.INTERRUPTED)
    except BrokenPipeError:
        return int(ExitCode.OK)
