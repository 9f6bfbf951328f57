"""``spm-console warm-start``: the resident warm start of the motion process, shown or ended.

The resident (:mod:`spm_console.system.resident`) keeps what a motion process imports
loaded between commands, so a moving command's motion process is ready in milliseconds. It
ends by itself when idle; ``--stop`` ends it now (once its motion processes have ended).
"""

from __future__ import annotations

import argparse
import os
from typing import Any

from spm_console.cli.common import emit
from spm_console.errors import ExitCode
from spm_console.services.warm_start import ENV_WARM_START, mode
from spm_console.system import resident


def register(sub: Any) -> None:
    p = sub.add_parser("warm-start", help="show or stop the resident warm start of motion "
                                          "processes")
    p.add_argument("--stop", action="store_true",
                   help="end it (it finishes its running motion processes first)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=cmd_warm_start)


def cmd_warm_start(args: argparse.Namespace) -> int:
    path = resident.socket_path()
    pid = None if path is None else resident.running(path)
    stopped = None
    if args.stop and path is not None and pid is not None:
        stopped = resident.stop(path)
    how = mode()
    rec = {"mode": how, "socket": path, "pid": pid, "stopped": stopped is not None,
           "idle_s": resident.idle_from_env(),
           "environment": os.environ.get(ENV_WARM_START, "")}
    if pid is None:
        human = "no resident warm start runs for this installation"
    elif stopped is not None:
        human = f"resident warm start {pid} stopped"
    else:
        human = f"resident warm start {pid} listens on {path}"
    if how != "resident":
        human += f" (this environment starts motion processes {how}: {ENV_WARM_START}=" \
                 f"{os.environ.get(ENV_WARM_START, '')})"
    emit(args, rec, human)
    return int(ExitCode.OK)
