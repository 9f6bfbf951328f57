"""``script`` command: run a scripted session headless (format: :mod:`spm_console.scripting.runner`).

Progress lines go to stderr; one JSON summary goes to stdout. The exit code is the
first failing step's (11 for a failed assertion, 20–25 for a safety stop).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from spm_console.cli.common import EMITTED, info, output_may_be_gone, to_jsonable
from spm_console.cli.streams import stdout_guard
from spm_console.config.load import load_profile
from spm_console.scripting.steps import load_script


def register(sub: Any) -> None:
    p = sub.add_parser("script", help="run a scripted session (home, fk, workspace, plan, "
                       "execute, wait, assert) headless; JSON summary on stdout")
    p.add_argument("file", type=Path, metavar="FILE.toml", help="the script")
    p.add_argument("--profile", default=None,
                   help="profile TOML file (default: the script's [session] profile, else "
                   "profiles/agile_wrist.toml)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--port", metavar="DEV", help="serial port (overrides the script)")
    g.add_argument("--sim", action="store_true", help="use the emulated bus (overrides the script)")
    p.add_argument("--logs", type=Path, default=None, metavar="DIR", help="run log folder")
    p.add_argument("--json", action="store_true", help="accepted for symmetry: the summary is "
                   "always JSON")
    p.set_defaults(func=cmd_script)


def cmd_script(args: argparse.Namespace) -> int:
    from spm_console.scripting.runner import run_script, session_for

    script = load_script(args.file)
    profile = load_profile(args.profile) if args.profile else None
    session = session_for(script, profile, port=args.port, sim=args.sim, logs=args.logs)
    info(f"script {args.file}: {len(script.step)} steps on the {session.bus_label}, "
         f"profile {session.profile.name}")

    def progress(line: str) -> None:
        with output_may_be_gone():  # a progress line after SIGHUP must not end the script
            info(line)

    runner = run_script(script, session, progress)
    summary = runner.summary()
    EMITTED.set()  # the summary is the command's one JSON object: a later failure adds none
    with output_may_be_gone():  # after SIGHUP the terminal is gone: the exit code still tells
        stdout_guard.out().write(json.dumps(to_jsonable(summary)) + "\n")
        stdout_guard.out().flush()
        info(("done: " if summary["ok"] else "FAILED: ") + summary["message"])
    return int(runner.exit_code)
