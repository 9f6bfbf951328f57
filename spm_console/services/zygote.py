"""The warm start of the motion process: a small process that has already imported what a
motion process needs, and forks one on request.

A motion process started from scratch spends about 2 s importing (numpy, scipy, the Kalman
filters' scipy.stats, the follower's QP solver) before it answers. This process imports all
that once; each motion process is then a fork of it, ready in milliseconds
(:mod:`spm_console.services.warm_start` is the front end's side). It runs in one of two ways:

* **for one front end** (``python -m spm_console.services.zygote --fd N``): started by that
  front end on a socket pair, it ends when its owner closes the socket (or exits);
* **resident** (``--listen PATH``, :mod:`spm_console.system.resident`): one per user and
  installation, shared by the front ends that connect to ``PATH``. It outlives the command
  that started it, so a command's motion process is ready at once from the second command
  on. Its lifetime: it ends after an idle time with no connection and no motion process,
  on SIGTERM, and as soon as the code it imported has changed on disk (the stale-code rule,
  checked on every connection: that front end is told, and starts a fresh one). Once
  retired it accepts nothing new and ends when its last motion process has ended.

What a fork gets, and what it does not:

* it runs in a session of its own (``setsid``), like a motion process started directly: a
  signal to the front end's process group or terminal never reaches the servo loop;
* the asking front end's environment, working directory, umask, CPU affinity and standard
  error *of the moment it asks* (sent with the request): the CPU plan, the cache and log
  folders are read from them; a front end niced below this process is refused (its motion
  process is then started directly);
* the default disposition of the terminating signals and SIGCHLD; every socket of this
  process is closed in it; it starts only once its asker holds its pid and pidfd (a failure
  before that kills it before it has read anything);
* this process starts no thread (numpy's BLAS may: its own fork handler stops them).

What the fork does *not* get anew: what Python fixed when this process started (``sys.path``,
the interpreter's ``PYTHON*`` settings, locale, time zone), and its limits.

It ignores SIGINT, SIGHUP and SIGQUIT; for one front end, SIGTERM too (its owner ends it).
It reaps its forks and reports each one's exit status to the front end that asked.

Messages (``SOCK_SEQPACKET``, one JSON object each): on connection this process says
``{"ready": PID}`` (or ``{"stale": "why"}`` / ``{"unsupported": "why"}`` and closes); a front
end sends ``{"id": K, "env": {...}, "cwd": "...", "umask": U, "cpus": [...], "nice": N}``
with the motion process's end of its socket pair and its standard error attached; this
process answers ``{"id": K, "pid": N}`` with a pidfd of the fork attached (race-free waiting
and signalling for the front end, which is not the fork's parent) or ``{"id": K, "error":
"..."}``, and later ``{"exit": N, "code": C}`` when the fork has ended.

A helper (the emulated bus's process, :mod:`.zygote_forks`) is asked for the same way, with
``"helper": MODULE, "parent": PID`` added and the ends of its standard input and output
attached instead: it is the helper a front end would start as ``python -m MODULE --parent
PID``, without the imports.
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
import time
import traceback
from collections.abc import Sequence

from spm_console.services.zygote_forks import HELPER_IMPORTS, Request, run_helper, run_motion_process
from spm_console.system import resident, rundir
from spm_console.system.signals import STOP_SIGNALS

#: What a motion process imports before it answers, and what only a motion needs; then what
#: the helpers it forks import (the emulated bus's child: the profile's schema, the servos).
PRELOAD = ("spm_console.motion.server", "filterpy.kalman", "spm_console.motion.follow.run",
           *HELPER_IMPORTS)
#: Largest request accepted, bytes (an environment of a few kB).
MAX_MESSAGE = 1 << 20
#: How often finished forks are reaped when no request comes, s.
REAP_PERIOD_S = 0.1
#: Most front ends connected to a resident warm start at once.
MAX_CONNECTIONS = 64


def _send(sock: socket.socket, msg: dict[str, object], fds: Sequence[int] = ()) -> None:
    socket.send_fds(sock, [json.dumps(msg).encode()], list(fds))


class Zygote:
    """The serving loop: the owner's connection (for one front end), or a listening socket
    and the front ends connected to it (resident)."""

    def __init__(self, *, owner: socket.socket | None = None,
                 listener: resident.Listener | None = None, idle_s: float = 0.0) -> None:
        self.listener = listener
        self.idle_s = idle_s
        self.conns: list[socket.socket] = [owner] if owner is not None else []
        self.forks: dict[int, socket.socket] = {}  # pid → the connection that asked
        self.retired = listener is None
        self.stamp: resident.CodeStamp | None = None  # set once the preload is done
        self.terminated = False  # SIGTERM (resident): retire at the next turn of the loop
        self.last_active = time.monotonic()

    # -- forks -------------------------------------------------------------------------
    def _fork(self, fd: int, err: int, req: Request, go: int, go_w: int) -> int:
        """Fork; the child waits for one byte on ``go`` (the parent has told the asker its pid
        and pidfd), then runs the motion process on ``fd`` (or the helper asked for, on its
        standard input ``fd`` and output ``err``); it never returns. Without that byte it
        leaves at once, having touched nothing."""
        pid = os.fork()
        if pid:
            return pid
        code = 1
        try:
            try:
                for s in self.conns:
                    s.close()
                if self.listener is not None:
                    self.listener.close_in_fork()
                os.close(go_w)  # the parent's end: closed without a byte, the read below ends
                if os.read(go, 1) == b"g":
                    os.close(go)
                    code = (run_helper(fd, err, req) if req.helper
                            else run_motion_process(fd, err, req))
            except BaseException:  # a bug: say so on stderr, then leave like a crashed process
                with contextlib.suppress(BaseException):
                    traceback.print_exc()
            finally:
                with contextlib.suppress(BaseException):
                    sys.stdout.flush()
                    sys.stderr.flush()
        finally:
            os._exit(code)

    def _answer(self, sock: socket.socket, data: bytes, fds: list[int]) -> None:
        """Fork one motion process for a request and tell its asker (id, pid, pidfd); on any
        failure the fork is killed before it has read anything, and the asker told why."""
        fd, err = fds[0], (fds[1] if len(fds) > 1 else -1)
        go_r, go_w = os.pipe()
        pid, ident = 0, None
        try:
            with contextlib.suppress(ValueError, AttributeError):
                ident = json.loads(data).get("id")
            req = Request.parse(data)
            if req.helper and err < 0:
                raise ValueError("a helper needs the ends of its standard input and output")
            if self.retired and self.listener is not None:
                raise OSError("this warm start is retired: it forks nothing new")
            if req.nice < os.getpriority(os.PRIO_PROCESS, 0):
                raise OSError("the front end runs at a higher priority than this warm start")
            pid = self._fork(fd, err, req, go_r, go_w)
            pidfd = os.pidfd_open(pid)  # before any reaping: race-free
            try:
                _send(sock, {"id": ident, "pid": pid}, [pidfd])
            finally:
                os.close(pidfd)
            self.forks[pid] = sock
            if self.listener is not None:  # who asked: the bus's lock names it
                rundir.note_front_end(self.listener.folder, pid, self.listener.peer_pid(sock))
            os.write(go_w, b"g")
        except Exception as exc:  # the asker is told, and the fork never runs
            if pid:
                self.forks.pop(pid, None)
                with contextlib.suppress(OSError):
                    os.kill(pid, signal.SIGKILL)
            with contextlib.suppress(OSError):
                _send(sock, {"id": ident, "error": f"{type(exc).__name__}: {exc}"})
        finally:
            for f in (go_r, go_w, *fds):
                os.close(f)

    def _reap(self) -> None:
        while True:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                return
            if pid == 0:
                return
            asker = self.forks.pop(pid, None)
            if self.listener is not None:
                rundir.forget_front_end(self.listener.folder, pid)
            if asker is not None and asker in self.conns:
                with contextlib.suppress(OSError):
                    _send(asker, {"exit": pid, "code": os.waitstatus_to_exitcode(status)})

    # -- connections -------------------------------------------------------------------
    def _accept(self) -> None:
        assert self.listener is not None and self.stamp is not None
        conn = self.listener.accept()
        if conn is None:
            return
        if len(self.conns) >= MAX_CONNECTIONS:
            conn.close()
            return
        changed = self.stamp.changed()
        if changed:
            self.retire()  # first: the front end told may start a fresh one at once
            with contextlib.suppress(OSError):
                _send(conn, {"stale": f"its code changed on disk ({changed})"})
            conn.close()
            return
        try:
            _send(conn, {"ready": os.getpid()})
        except OSError:
            conn.close()
            return
        self.conns.append(conn)

    def _read(self, sock: socket.socket) -> None:
        try:
            data, fds, _, _ = socket.recv_fds(sock, MAX_MESSAGE, 2)
        except OSError:
            data, fds = b"", []
        if not data:
            for f in fds:
                os.close(f)
            self.conns.remove(sock)
            sock.close()
            return
        if not 1 <= len(fds) <= 2:
            for f in fds:
                os.close(f)
            return
        self._answer(sock, data, fds)

    def retire(self) -> None:
        """Accept nothing new (resident): the path is freed for a fresh warm start."""
        self.retired = True
        if self.listener is not None:
            self.listener.release()

    def _done(self) -> bool:
        if self.listener is None:
            return not self.conns  # the owner closed its socket
        if self.terminated and not self.retired:
            self.retire()
        if self.conns or self.forks:
            self.last_active = time.monotonic()
        elif time.monotonic() - self.last_active > self.idle_s:
            self.retire()
        return self.retired and not self.forks

    def serve(self) -> None:
        """Answer until done: the owner gone (for one front end); retired with no motion
        process left (resident)."""
        self.last_active = time.monotonic()  # idle from now, not from before the imports
        while not self._done():
            waiting = list(self.conns)
            if self.listener is not None and not self.retired:
                waiting.append(self.listener.sock)
            try:
                ready, _, _ = select.select(waiting, [], [], REAP_PERIOD_S)
            except InterruptedError:
                ready = []
            self._reap()
            for s in ready:
                if self.listener is not None and s is self.listener.sock:
                    self._accept()
                elif s in self.conns:
                    self._read(s)


def _pidfd_support() -> str:
    """"" when this kernel gives pidfds (Linux 5.3), else why not."""
    try:
        os.close(os.pidfd_open(os.getpid()))
    except (AttributeError, OSError) as exc:
        return f"no pidfd: {exc}"
    return ""


def _preload() -> None:
    for name in PRELOAD:
        importlib.import_module(name)
    gc.collect()
    gc.freeze()  # the forks share the preloaded objects' pages instead of copying them


def _serve_owner(fd: int) -> int:
    for sig in STOP_SIGNALS:  # its owner ends it by closing the socket
        signal.signal(sig, signal.SIG_IGN)
    sock = socket.socket(fileno=fd)
    why_not = _pidfd_support()
    if why_not:
        with contextlib.suppress(OSError):
            _send(sock, {"unsupported": why_not})
        return 0
    _preload()
    try:
        _send(sock, {"ready": os.getpid()})
    except OSError:
        return 0
    Zygote(owner=sock).serve()
    return 0


def _serve_resident(path: str, idle_s: float) -> int:
    for sig in STOP_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)
    if _pidfd_support():
        return 0  # its front ends find no socket and start their motion processes otherwise
    listener = resident.Listener.bind(path)
    if listener is None:
        return 0  # another one holds this path
    zygote = Zygote(listener=listener, idle_s=idle_s)

    def _terminate(_sig: int, _frame: object) -> None:
        zygote.terminated = True

    signal.signal(signal.SIGTERM, _terminate)
    _preload()
    zygote.stamp = resident.CodeStamp.now()  # what was imported, as it is on disk now
    zygote.serve()
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="spm_console warm start of motion processes "
                                                 "(started by a front end)")
    how = parser.add_mutually_exclusive_group(required=True)
    how.add_argument("--fd", type=int, help="serve the owner on this socket")
    how.add_argument("--listen", metavar="PATH", help="serve as the resident warm start")
    parser.add_argument("--idle", type=float, default=resident.IDLE_DEFAULT_S,
                        help="resident: seconds without use before it ends")
    args = parser.parse_args(argv)
    signal.signal(signal.SIGCHLD, signal.SIG_DFL)  # reaped here, whatever the launcher ignored
    if args.fd is not None:
        return _serve_owner(args.fd)
    return _serve_resident(args.listen, resident.bounded_idle(args.idle))


if __name__ == "__main__":
    raise SystemExit(main())
