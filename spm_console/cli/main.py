"""Entry point of ``spm-console``: one parser, one mapping from error to exit code."""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from spm_console import __version__
from spm_console.errors import ExitCode, SpmError

#: Command name -> the module that registers it (``register(subparsers)`` setting ``func``).
#: Only the module of the command being run is imported, so start-up stays fast (the TUI,
#: for one, does not pay for cvxpy or matplotlib); ``--help`` imports them all.
COMMANDS: dict[str, str] = {
    "fk": "spm_console.cli.kin",
    "ik": "spm_console.cli.kin",
    "servo": "spm_console.cli.servo",
    "emulate": "spm_console.cli.servo",
    "workspace": "spm_console.cli.workspace",
    "plan": "spm_console.cli.plan",
    "identify": "spm_console.cli.plan",
    "tui": "spm_console.cli.tui",
    "script": "spm_console.cli.script",
    "home": "spm_console.cli.run",
    "execute": "spm_console.cli.run",
    "logs": "spm_console.cli.logs",
    "reproduce": "spm_console.cli.reproduce",
}
COMMAND_MODULES = list(dict.fromkeys(COMMANDS.values()))


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The CLI parser; with ``command``, only that command's module is imported."""
    parser = argparse.ArgumentParser(
        prog="spm-console",
        description="Operator console for 3-DOF spherical parallel manipulators "
        "(degrees, mm, seconds at every interface).",
    )
    parser.add_argument("--version", action="version", version=f"spm-console {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    modules = [COMMANDS[command]] if command in COMMANDS else COMMAND_MODULES
    for name in modules:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args_list = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(args_list[0] if args_list else None)
    try:
        args = parser.parse_args(args_list)
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
