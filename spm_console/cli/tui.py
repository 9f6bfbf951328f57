"""``tui`` command: the operator console (Textual) on a serial port or the emulated bus.

The console's settings (ctrl+o / F7: profile and workspace grid step), and the servo model
its identification found (step 1, key i), restart it: the app exits with a
:class:`~spm_console.tui.switch.SwitchRequest` after closing its session, and
:func:`run_consoles` starts the next console in the same terminal.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

from spm_console.cli.common import add_plant, console_plant, number, with_plant
from spm_console.config.load import load_profile, with_grid_step
from spm_console.config.schema import DEFAULT_PROFILE
from spm_console.input_rules import finite_number


def register(sub: Any) -> None:
    p = sub.add_parser("tui", help="operator console: connect, home, FK, workspace, plan, execute, logs")
    p.add_argument("--profile", default=str(DEFAULT_PROFILE),
                   help=f"profile TOML file (default {DEFAULT_PROFILE}); the console's settings "
                        "(ctrl+o or F7) switch to another one")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--port", metavar="DEV", help="serial port of the servo bus (e.g. /dev/ttyUSB0)")
    g.add_argument("--sim", action="store_true",
                   help="use the emulated servo bus (default when neither --port nor the "
                   "profile's bus.port is set)")
    add_plant(p, "the profile's [plant] model when it names one, else physical")
    p.add_argument("--no-viewer", action="store_true", help="do not start the meshcat 3D view")
    p.add_argument("--grid-step", type=number, default=None, metavar="DEG",
                   help="workspace grid step Δ instead of the profile's (e.g. 1 for the paper's "
                        "minimum-time pair); the workspace, the runtime's plan verification and "
                        "plan files all use it; the console's settings change it too")
    p.add_argument("--logs", type=Path, default=None, metavar="DIR",
                   help="run log folder (default logs/ or $SPM_CONSOLE_LOGS)")
    p.add_argument("--cache-dir", type=Path, default=None, metavar="DIR",
                   help="workspace cache folder (default: the workspace command's cache)")
    p.set_defaults(func=cmd_tui)


class ConsoleApp(Protocol):
    """What :func:`run_consoles` needs of a console: run it, then close it."""

    def run(self) -> Any: ...

    def shutdown(self) -> None: ...


#: How long the threads left after the last console closed may take to end, s.
LINGER_S = 2.0


def end_if_threads_linger(code: int, before: set[threading.Thread],
                          wait_s: float = LINGER_S) -> None:
    """After the last console has closed (its session, run log and viewer closed), end the
    process with ``code`` if a thread started since ``before`` (not a daemon) would keep it
    alive past ``wait_s``; a normal quit leaves none. A terminal that went away while the
    console was ending (its pseudo-terminal deleted) can leave the UI library's input thread
    reading end-of-file in a loop and its output thread waiting: the interpreter waited for
    them for good (seen: a console at 83 % of a CPU long after a test closed its terminal)."""
    t_end = time.monotonic() + wait_s
    left = [t for t in threading.enumerate() if t not in before and not t.daemon]
    for t in left:
        t.join(max(0.0, t_end - time.monotonic()))
    if any(t.is_alive() for t in left):
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(OSError, ValueError):  # the terminal is gone
                stream.flush()
        os._exit(code)


#: Builds the console for a profile file and an optional grid step (deg; None: the
#: profile's own), with a note to show once it is up, and the workspace the console before
#: kept (a ``KeptWorkspace`` of the console app's module, or None).
ConsoleFactory = Callable[[Path, "float | None", str, Any], ConsoleApp]


def run_consoles(profile_path: Path, grid_step_deg: float | None,
                 factory: ConsoleFactory) -> int:
    """Run consoles until one exits with an exit code: each app is closed (its session
    E-stops any motion and closes the motion process; the viewer closes) before the next
    one, built for the settings the operator applied (or the identified servo model), starts
    in the same terminal with the workspace the request kept."""
    from spm_console.tui.app import SwitchRequest

    note, kept = "", None
    while True:
        app = factory(profile_path, grid_step_deg, note, kept)
        try:
            result = app.run()
        finally:
            app.shutdown()
        if not isinstance(result, SwitchRequest):
            return int(result or 0)
        profile_path, grid_step_deg = result.profile_path, result.grid_step_deg
        note, kept = result.note(), result.kept


def console_factory(args: argparse.Namespace) -> ConsoleFactory:
    """The consoles ``spm-console tui`` runs: the profile file (at a grid step) on the bus
    and with the views its options name."""

    def factory(path: Path, step_deg: float | None, note: str, kept: Any) -> ConsoleApp:
        from spm_console.tui.app import make_app

        loaded = load_profile(path)
        profile = with_plant(loaded, console_plant(loaded, getattr(args, "plant", None)))
        if step_deg is not None:
            profile = with_grid_step(profile, step_deg)
        port = args.port or (None if args.sim else (profile.bus.port or None))
        return make_app(profile, port=port, sim=port is None, viewer=not args.no_viewer,
                        logs_root=args.logs, cache_dir=args.cache_dir, profile_path=path,
                        note=note, kept=kept)

    return factory


def cmd_tui(args: argparse.Namespace) -> int:
    grid = args.grid_step
    if grid is not None:
        grid = finite_number(grid, "--grid-step", 0.0, 30.0, lo_open=True)

    before = set(threading.enumerate())
    code = run_consoles(Path(args.profile), grid, console_factory(args))
    end_if_threads_linger(code, before)
    return code
