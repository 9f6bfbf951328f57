"""Entry point of ``spm-console``: one parser, one mapping from error to exit code."""

from __future__ import annotations

import argparse
import importlib
import json
import signal
import sys
import threading
from collections.abc import Sequence
from types import FrameType
from typing import NoReturn

from spm_console import __version__
from spm_console.cli.streams.stdout_guard import json_stdout, out
from spm_console.errors import ExitCode, RefusedError, SpmError
from spm_console.refusals import worded
from spm_console.services.warm_start import mode, prestart
from spm_console.system.childproc import prespawn
from spm_console.system.cpus import cpu_plan
from spm_console.system.signals import (
    SignalInterrupt,
    forget_signals,
    ignore_stop_signals,
    note_raised,
    note_signal,
    raised_interrupt,
)

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
    "identify": "spm_console.cli.identify",
    "tui": "spm_console.cli.tui",
    "script": "spm_console.cli.script",
    "home": "spm_console.cli.run",
    "execute": "spm_console.cli.run",
    "follow": "spm_console.cli.follow",
    "logs": "spm_console.cli.logs",
    "reproduce": "spm_console.cli.tools.reproduce",
    "latency": "spm_console.cli.tools.latency",
    "export": "spm_console.cli.tools.export",
    "design": "spm_console.cli.design",
    "commission": "spm_console.cli.commission",
    "warm-start": "spm_console.cli.tools.warm",
}
COMMAND_MODULES = list(dict.fromkeys(COMMANDS.values()))


class UsageError(SystemExit):
    """A bad command line (exit 2), with argparse's reason for the ``--json`` object."""

    def __init__(self, message: str) -> None:
        super().__init__(int(ExitCode.USAGE))
        self.message = message


class CliParser(argparse.ArgumentParser):
    """argparse's parser (usage and reason on stderr, exit 2) whose usage errors keep their
    reason; its subparsers are of the same class (argparse's default)."""

    def error(self, message: str) -> NoReturn:
        self.print_usage(sys.stderr)
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        raise UsageError(f"{self.prog}: {message}")


def _wants_json(args: Sequence[str]) -> bool:
    """Whether the command line asks for JSON (before it is parsed, for usage errors)."""
    return "--json" in (a for a in args if a != "--")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The CLI parser; with ``command``, only that command's module is imported."""
    parser = CliParser(
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


def _interrupt(signum: int, _frame: FrameType | None) -> None:
    if note_signal(signal.Signals(signum)):  # the first decides; a second changes nothing
        # kept, so that an interrupt a library catches still decides (a run's own stop
        # handler raises nothing and keeps nothing here)
        note_raised(signal.Signals(signum))
        raise SignalInterrupt(signal.Signals(signum).name)


def _interrupt_on_signals() -> None:
    """Until a command installs its own stop handling (a run E-stops; see system/signals.py),
    SIGINT (Ctrl-C), SIGTERM, SIGHUP and SIGQUIT end the process: exit 130 with a message. The
    first one decides; a second one changes nothing. A signal already ignored (``nohup``, a
    shell's background job) stays ignored."""
    if threading.current_thread() is not threading.main_thread():
        return
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT):
        if signal.getsignal(sig) is not signal.SIG_IGN:
            signal.signal(sig, _interrupt)


def _fail(as_json: bool, code: int, message: str) -> int:
    """The error on stderr; with --json also ``{"ok": false, ...}`` on stdout."""
    sys.stderr.write(f"error: {message}\n")
    common = sys.modules.get("spm_console.cli.common")
    if as_json and not (common is not None and common.EMITTED.is_set()):
        out().write(json.dumps({"ok": False, "exit_code": code, "error": message}) + "\n")
        out().flush()
    return code


def main(argv: Sequence[str] | None = None) -> int:
    """The command line ``argv`` (default: the process's, as its entry point); the exit code.
    As the entry point, once the code is decided a terminating signal no longer changes it."""
    forget_signals()
    _interrupt_on_signals()
    common = sys.modules.get("spm_console.cli.common")
    if common is not None:  # in-process callers (tests) run main() more than once
        common.EMITTED.clear()
    args_list = list(sys.argv[1:] if argv is None else argv)
    code: int | None = None
    try:
        # with --json, stdout carries the JSON object only, whatever a library prints
        # (a script's summary is always JSON)
        with json_stdout(_wants_json(args_list) or args_list[:1] == ["script"]):
            code = _main(args_list)
    except KeyboardInterrupt:  # the first signal, after the command's own handling
        pass
    finally:
        if argv is None:
            ignore_stop_signals()
    return int(ExitCode.INTERRUPTED) if code is None else code


#: Commands whose first motion process is asked for soon: its warm start begins at once. Not
#: the console: its first screen comes first (the warm start's imports beside its own put the
#: screen off by half a second on two cores).
MOVING_COMMANDS = frozenset({"execute", "home", "follow", "script"})
#: The emulated bus's process (:class:`spm_console.devices.emulator.child.EmulatorChild`).
EMULATOR_CHILD = "spm_console.devices.emulator.child"


def _main(args_list: list[str]) -> int:
    as_json = _wants_json(args_list) or args_list[:1] == ["script"]  # (a script's: always)
    moving = args_list[:1] and (args_list[0] in MOVING_COMMANDS or (
        args_list[0] == "identify" and "--experiment" in args_list))
    if moving and "--help" not in args_list:
        prestart()  # its imports overlap this process's own (the command's module, the profile)
        if "--sim" in args_list and mode() != "direct":  # the emulated bus's child too: it
            # imports, then waits (SPM_CONSOLE_WARM_START=0: nothing is started ahead)
            cpu_plan()  # fixed before any child starts (see spm_console.system.cpus)
            prespawn(EMULATOR_CHILD)
    try:
        parser = build_parser(args_list[0] if args_list else None)
        try:
            args = parser.parse_args(args_list)
        except SystemExit as exc:  # argparse: usage errors exit 2, --help exits 0
            code = int(exc.code or 0)
            if code and as_json:  # the reason is on stderr too, after the usage line
                why = exc.message if isinstance(exc, UsageError) else "bad command line"
                out().write(json.dumps({"ok": False, "exit_code": code, "error": why}) + "\n")
            return code
        if not getattr(args, "func", None):
            parser.print_help(sys.stderr)
            if as_json:
                out().write(json.dumps({"ok": False, "exit_code": int(ExitCode.USAGE),
                                        "error": "no command given"}) + "\n")
            return int(ExitCode.USAGE)
        as_json = as_json or bool(getattr(args, "json", False))
        return int(args.func(args))
    except SpmError as exc:
        message = worded(exc.reason, "cli") if isinstance(exc, RefusedError) else exc.message
        return _fail(as_json, int(exc.exit_code), message)
    except KeyboardInterrupt as exc:
        why = f" by {exc.args[0]}" if exc.args else ""
        return _fail(as_json, int(ExitCode.INTERRUPTED), f"interrupted{why}")
    except BrokenPipeError:
        return int(ExitCode.OK)
    except Exception:
        # The start-up handler's SignalInterrupt raised inside a library that wraps what it
        # catches (pydantic builds its validators as modules load and turns the interrupt into
        # a SchemaError): the signal decided, as if it had arrived a bytecode earlier. Anything
        # else — no signal, or a signal a command's own stop handler took — is a bug.
        sig = raised_interrupt()
        if sig is None:
            raise
        return _fail(as_json, int(ExitCode.INTERRUPTED), f"interrupted by {sig.name}")
