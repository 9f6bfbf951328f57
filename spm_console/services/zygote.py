"""The warm start of the motion process: a small process that has already imported what a
motion process needs, and forks one on request.

A motion process started from scratch spends about 2 s importing (numpy, scipy, the Kalman
filters' scipy.stats, the follower's QP solver) before it answers. A front end that starts
several in its life (the console restarts it when the profile changes; scripted sessions
and test suites connect many times) starts this process once, with
``python -m spm_console.services.zygote --fd N``; each motion process is then a fork of it,
ready in milliseconds (:mod:`spm_console.services.warm_start` is the front end's side).

What a fork gets, and what it does not:

* it runs in a session of its own (``setsid``), like a motion process started directly: a
  signal to the front end's process group or terminal never reaches the servo loop;
* the front end's environment and working directory *of the moment it asks* (sent with the
  request): the CPU plan, the cache and log folders are read from them;
* the default disposition of the terminating signals and SIGCHLD; this process's socket is
  closed in it; it starts only once its owner holds its pid and pidfd (a failure before
  that kills it before it has read anything);
* this process starts no thread (numpy's BLAS may: its own fork handler stops them).

What the fork does *not* get anew: what Python fixed when this process started (``sys.path``,
the interpreter's ``PYTHON*`` settings, locale, time zone), and its scheduling and limits.

This process ignores the terminating signals: its owner ends it by closing the socket (or
by exiting, which closes it). It reaps its forks and reports each one's exit status.

Messages (``SOCK_SEQPACKET``, one JSON object each): the owner sends
``{"id": K, "env": {...}, "cwd": "..."}`` with the motion process's end of its socket pair
attached; this process answers ``{"id": K, "pid": N}`` with a pidfd of the fork attached
(race-free waiting and signalling for the owner, who is not the fork's parent) or
``{"id": K, "error": "..."}``, and later ``{"exit": N, "code": C}`` when the fork has ended.
On a kernel without pidfds it answers ``{"unsupported": "..."}`` instead of ``{"ready": PID}``
and ends (its owner then starts motion processes directly).
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import importlib
import json
import os
import select
import signal
import socket
import sys
import traceback
from collections.abc import Sequence

from spm_console.system.signals import STOP_SIGNALS

#: What a motion process imports before it answers, and what only a motion needs.
PRELOAD = ("spm_console.motion.server", "filterpy.kalman", "spm_console.motion.follow.run")
#: Largest request accepted, bytes (an environment of a few kB).
MAX_MESSAGE = 1 << 20
#: How often finished forks are reaped when no request comes, s.
REAP_PERIOD_S = 0.1


def _send(sock: socket.socket, msg: dict[str, object], fds: Sequence[int] = ()) -> None:
    socket.send_fds(sock, [json.dumps(msg).encode()], list(fds))


def _fork_motion_process(sock: socket.socket, fd: int, env: dict[str, str], cwd: str,
                         go: int, go_w: int) -> int:
    """Fork; the child waits for one byte on ``go`` (the parent has told the owner its pid and
    pidfd), then runs the motion process on ``fd``; it never returns. Without that byte it
    leaves at once, having touched nothing."""
    pid = os.fork()
    if pid:
        return pid
    code = 1
    try:
        try:
            sock.close()
            os.close(go_w)  # the parent's end: closed without a byte, the read below ends
            if os.read(go, 1) == b"g":
                os.close(go)
                os.setsid()
                for sig in (*STOP_SIGNALS, signal.SIGCHLD):
                    signal.signal(sig, signal.SIG_DFL)
                os.environ.clear()
                os.environ.update(env)
                os.chdir(cwd)
                from spm_console.motion import server

                sys.argv = [server.__file__, "--fd", str(fd)]  # what the run logs record
                code = server.main(["--fd", str(fd)])
        except BaseException:  # a bug: say so on stderr, then leave like a crashed process
            with contextlib.suppress(BaseException):
                traceback.print_exc()
        finally:
            with contextlib.suppress(BaseException):
                sys.stdout.flush()
                sys.stderr.flush()
    finally:
        os._exit(code)


def _reap(sock: socket.socket) -> None:
    while True:
        try:
            pid, status = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            return
        _send(sock, {"exit": pid, "code": os.waitstatus_to_exitcode(status)})


def _answer(sock: socket.socket, req: dict[str, object], fd: int) -> None:
    """Fork one motion process for request ``req`` and tell the owner (id, pid, pidfd); on
    any failure the fork is killed before it has read anything, and the owner told why."""
    ident = req.get("id")
    go_r, go_w = os.pipe()
    pid = 0
    try:
        env = req["env"]
        assert isinstance(env, dict)
        pid = _fork_motion_process(sock, fd, {str(k): str(v) for k, v in env.items()},
                                   str(req["cwd"]), go_r, go_w)
        pidfd = os.pidfd_open(pid)  # before any reaping: race-free
        try:
            _send(sock, {"id": ident, "pid": pid}, [pidfd])
        finally:
            os.close(pidfd)
        os.write(go_w, b"g")
    except Exception as exc:  # the owner is told, and the fork never runs
        if pid:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
        with contextlib.suppress(OSError):
            _send(sock, {"id": ident, "error": f"{type(exc).__name__}: {exc}"})
    finally:
        os.close(go_r)
        os.close(go_w)
        os.close(fd)


def serve(sock: socket.socket) -> None:
    """Answer fork requests until the owner closes the socket."""
    while True:
        ready, _, _ = select.select([sock], [], [], REAP_PERIOD_S)
        try:
            _reap(sock)
            if not ready:
                continue
            data, fds, _, _ = socket.recv_fds(sock, MAX_MESSAGE, 1)
        except OSError:  # the owner is gone
            return
        if not data:
            return
        if len(fds) != 1:
            for f in fds:
                os.close(f)
            continue
        _answer(sock, json.loads(data), fds[0])


def _pidfd_support() -> str:
    """"" when this kernel gives pidfds (Linux 5.3), else why not."""
    try:
        os.close(os.pidfd_open(os.getpid()))
    except (AttributeError, OSError) as exc:
        return f"no pidfd: {exc}"
    return ""


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="spm_console warm start of motion processes "
                                                 "(started by a front end)")
    parser.add_argument("--fd", type=int, required=True)
    args = parser.parse_args(argv)
    for sig in STOP_SIGNALS:  # its owner ends it by closing the socket
        signal.signal(sig, signal.SIG_IGN)
    signal.signal(signal.SIGCHLD, signal.SIG_DFL)  # reaped here, whatever the launcher ignored
    sock = socket.socket(fileno=args.fd)
    why_not = _pidfd_support()
    if why_not:
        with contextlib.suppress(OSError):
            _send(sock, {"unsupported": why_not})
        return 0
    for name in PRELOAD:
        importlib.import_module(name)
    gc.collect()
    gc.freeze()  # the forks share the preloaded objects' pages instead of copying them
    try:
        _send(sock, {"ready": os.getpid()})
    except OSError:
        return 0
    serve(sock)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
