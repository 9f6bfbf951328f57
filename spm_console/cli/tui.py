"""``tui`` command: the operator console (Textual) on a serial port or the emulated bus."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from spm_console.cli.common import profile_of
from spm_console.profile import DEFAULT_PROFILE


def register(sub: Any) -> None:
    p = sub.add_parser("tui", help="operator console: connect, home, FK, workspace, plan, execute, logs")
    p.add_argument("--profile", default=str(DEFAULT_PROFILE),
                   help=f"profile TOML file (default {DEFAULT_PROFILE})")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--port", metavar="DEV", help="serial port of the servo bus (e.g. /dev/ttyUSB0)")
    g.add_argument("--sim", action="store_true",
                   help="use the emulated servo bus (default when neither --port nor the "
                   "profile's bus.port is set)")
    p.add_argument("--no-viewer", action="store_true", help="do not start the meshcat 3D view")
    p.add_argument("--grid-step", type=float, default=None, metavar="DEG",
                   help="workspace grid step Δ instead of the profile's (e.g. 1 for the paper's "
                        "minimum-time pair); the workspace, the runtime's plan verification and "
                        "plan files all use it")
    p.add_argument("--logs", type=Path, default=None, metavar="DIR",
                   help="run log folder (default logs/ or $SPM_CONSOLE_LOGS)")
    p.add_argument("--cache-dir", type=Path, default=None, metavar="DIR",
                   help="workspace cache folder (default: the workspace command's cache)")
    p.set_defaults(func=cmd_tui)


def cmd_tui(args: argparse.Namespace) -> int:
    from spm_console.tui.app import make_app

    profile = profile_of(args)
    if args.grid_step is not None:
        from spm_console.cli.common import finite_number
        from spm_console.profile import with_grid_step

        profile = with_grid_step(profile, finite_number(args.grid_step, "--grid-step", 0.0, 30.0,
                                                        lo_open=True))
    port = args.port or (None if args.sim else (profile.bus.port or None))
    app = make_app(profile, port=port, sim=port is None, viewer=not args.no_viewer,
                   logs_root=args.logs, cache_dir=args.cache_dir)
    try:
        code = app.run()
    finally:
        app.shutdown()
    return int(code or 0)
