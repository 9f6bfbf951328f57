"""A fork request to the warm start (:mod:`.zygote`), checked, and what the fork becomes once
released: the asker's motion process, or one of the helpers a front end starts beside it
(the emulated bus's process).

Either way it first takes the asker's session rules: a session of its own (``setsid``), the
default disposition of the terminating signals and SIGCHLD, the asker's environment, working
directory, umask, niceness and CPU set. Runs in the fork only.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import signal
import sys
from dataclasses import dataclass

from spm_console.system.signals import STOP_SIGNALS

#: The emulated bus's process (:mod:`spm_console.devices.emulator.child`).
EMULATOR_CHILD = "spm_console.devices.emulator.child"
#: The helpers a warm start forks: nothing else is run from a request.
HELPERS = frozenset({EMULATOR_CHILD})
#: What the helpers import before they answer: preloaded by the warm start.
HELPER_IMPORTS = (EMULATOR_CHILD, "spm_console.config.load", "spm_console.devices.emulator.bus",
                  "spm_console.system.simclock")


@dataclass(frozen=True)
class Request:
    """One fork request, checked: what the motion process (or helper) takes from its front
    end."""

    ident: object
    env: dict[str, str]
    cwd: str
    umask: int
    cpus: frozenset[int]
    nice: int
    helper: str = ""
    """The helper module the fork runs (one of :data:`.zygote_forks.HELPERS`); "": a motion
    process."""
    parent: int = 0
    """A helper's front end: it ends when that process is gone."""

    @classmethod
    def parse(cls, data: bytes) -> Request:
        """ValueError when the request is not one (its id, if any, is kept for the answer)."""
        msg = json.loads(data)
        if not isinstance(msg, dict):
            raise ValueError("not a request")
        env, cwd = msg.get("env"), msg.get("cwd")
        if not isinstance(env, dict) or not isinstance(cwd, str):
            raise ValueError("a request without environment or working directory")
        umask = msg.get("umask", 0o022)
        cpus = msg.get("cpus", sorted(os.sched_getaffinity(0)))
        nice = msg.get("nice", os.getpriority(os.PRIO_PROCESS, 0))
        if not (isinstance(umask, int) and 0 <= umask <= 0o777 and isinstance(nice, int)
                and isinstance(cpus, list) and cpus
                and all(isinstance(c, int) and 0 <= c < 4096 for c in cpus)):
            raise ValueError("a request with a bad umask, CPU set or niceness")
        helper, parent = msg.get("helper", ""), msg.get("parent", 0)
        if helper and (helper not in HELPERS or not isinstance(parent, int) or parent <= 0):
            raise ValueError(f"no helper {str(helper)[:80]!r} (or no parent for it) here")
        return cls(msg.get("id"), {str(k): str(v) for k, v in env.items()}, cwd, umask,
                   frozenset(cpus), nice, str(helper), int(parent) if helper else 0)


def _take_on(req: Request) -> None:
    os.setsid()
    for sig in (*STOP_SIGNALS, signal.SIGCHLD):
        signal.signal(sig, signal.SIG_DFL)
    os.environ.clear()
    os.environ.update(req.env)
    os.chdir(req.cwd)
    os.umask(req.umask)
    os.setpriority(os.PRIO_PROCESS, 0, req.nice)  # never below the warm start's: checked
    with contextlib.suppress(OSError):  # CPUs this process may not use: its own set stays
        os.sched_setaffinity(0, req.cpus)


def run_motion_process(fd: int, err: int, req: Request) -> int:
    """Become the asker's motion process on ``fd`` (its standard error ``err``, −1: keep)."""
    _take_on(req)
    if err >= 0:
        os.dup2(err, 2)
        os.close(err)
    from spm_console.motion import server

    sys.argv = [server.__file__, "--fd", str(fd)]  # what the run logs record
    return server.main(["--fd", str(fd)])


def run_helper(stdin_fd: int, stdout_fd: int, req: Request) -> int:
    """Become the helper ``req.helper`` as ``python -m HELPER --parent PID`` would run, on
    these ends of its standard input and output (standard error: /dev/null, as a helper
    started as a process of its own)."""
    _take_on(req)
    devnull = os.open(os.devnull, os.O_WRONLY)
    for fd, target in ((stdin_fd, 0), (stdout_fd, 1), (devnull, 2)):
        if fd != target:  # a warm start started without standard streams gets them as fds
            os.dup2(fd, target)
            os.close(fd)
    # the warm start's own streams may be closed or buffered: the helper's are new
    sys.stdin = io.TextIOWrapper(io.FileIO(0, "r", closefd=False), encoding="utf-8")
    sys.stdout = io.TextIOWrapper(io.FileIO(1, "w", closefd=False), encoding="utf-8",
                                  write_through=True)
    sys.stderr = io.TextIOWrapper(io.FileIO(2, "w", closefd=False), encoding="utf-8",
                                  write_through=True)
    if req.helper != EMULATOR_CHILD:  # checked with the request: never reached
        return 1
    from spm_console.devices.emulator import child

    args = ["--parent", str(req.parent)]
    sys.argv = [child.__file__, *args]
    return child.main(args)
