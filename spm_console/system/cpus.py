"""CPU placement: the processes that keep time on a CPU of their own, ours beside it.

Real-time priority decides who runs first *on a CPU*; it does not help a servo reply that
waits in the kernel. Every byte between the servo loop and the servos passes through the
tty layer's kernel workers (``flush_to_ldisc``: a USB serial adapter to real servos, or a
pseudo-terminal to emulated ones when ``emulator.link = "pty"``; the emulated bus's default
link, a socket, bypasses them), and those run at normal priority. Traced on a 2-core
machine, they waited up to 77 ms behind normal-priority processes on the same CPU (the
console's own UI process, the 3D view's server, a browser), long enough for three missed
replies in a row, a "communication lost" stop.

So, when asked and at least two CPUs are allowed, the servo loop's process and the emulated servos'
process run on one CPU (the highest-numbered allowed one, :func:`place_on_loop_cpu`) and
the console's other processes on the rest (:func:`place_beside_loop`). A kernel worker woken
on the loop's CPU then waits behind none of our normal-priority work (other programs may still
run there).
Other programs (a browser showing the 3D view) are not ours to place; see docs/cli-reference.md.

``SPM_CONSOLE_LOOP_CPU`` in the environment: ``off`` (default: no placement), ``auto`` (the
highest-numbered allowed CPU) or a CPU number. It is not the default because it halves what
the console itself gets: on 2 cores with the browser kept off the loop's CPU it removed the
communication-loss stops (0 of 20 console-driven runs against 5 of 10 with the browser on
every CPU), but with one busy process per core beside it 2 of 5 runs ended in a hold with
exit 20 (in one trial under heavier load: the motion process's heartbeat deadman, the console
having one CPU only). See docs/cli-reference.md. The first process that decides writes the CPU set it saw into
``SPM_CONSOLE_CPUS`` so that the children it starts, whose own affinity may already be
narrowed, decide alike.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

ENV_CHOICE = "SPM_CONSOLE_LOOP_CPU"
ENV_SET = "SPM_CONSOLE_CPUS"

_placed = ""
"""What this process's last placement did (for the run log), "" before any."""


@dataclass(frozen=True)
class CpuPlan:
    """Where our processes run; ``loop`` empty means no placement (and ``detail`` says why)."""

    loop: frozenset[int]
    rest: frozenset[int]
    detail: str

    @property
    def active(self) -> bool:
        return bool(self.loop) and bool(self.rest)


def _allowed() -> frozenset[int]:
    text = os.environ.get(ENV_SET, "")
    if text:
        try:
            cpus = frozenset(int(c) for c in text.split(",") if c.strip())
            if cpus:
                return cpus
        except ValueError:
            pass
    if not hasattr(os, "sched_getaffinity"):
        return frozenset()
    cpus = frozenset(os.sched_getaffinity(0))
    os.environ[ENV_SET] = ",".join(str(c) for c in sorted(cpus))
    return cpus


def cpu_plan() -> CpuPlan:
    """The placement for this machine and environment (see the module docstring)."""
    choice = os.environ.get(ENV_CHOICE, "off").strip().lower() or "off"
    if choice in ("off", "0-", "no", "none"):
        return CpuPlan(frozenset(), frozenset(),
                       f"no CPU placement ({ENV_CHOICE}=auto or a CPU number asks for it)")
    cpus = _allowed()
    if len(cpus) < 2:
        return CpuPlan(frozenset(), frozenset(),
                       f"no CPU placement: {len(cpus)} CPU allowed to this process")
    if choice == "auto":
        loop = max(cpus)
    else:
        try:
            loop = int(choice)
        except ValueError:
            return CpuPlan(frozenset(), frozenset(),
                           f"no CPU placement: {ENV_CHOICE}={choice!r} is not auto, off or a CPU")
        if loop not in cpus:
            return CpuPlan(frozenset(), frozenset(),
                           f"no CPU placement: CPU {loop} is not allowed to this process "
                           f"(allowed: {_fmt(cpus)})")
    rest = cpus - {loop}
    return CpuPlan(frozenset({loop}), rest,
                   f"servo loop and emulated servos on CPU {loop}, the console on {_fmt(rest)}")


def _fmt(cpus: frozenset[int]) -> str:
    return ",".join(str(c) for c in sorted(cpus))


def _threads() -> list[int]:
    try:
        return [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:
        return [0]


def _move_process(cpus: frozenset[int], *, skip_realtime: bool) -> str:
    """Every thread of this process onto ``cpus`` (threads started later inherit it from
    their creator). ``skip_realtime``: leave SCHED_FIFO threads (an in-process emulator)
    where they are. Returns "" or why it failed."""
    failed = ""
    for tid in _threads():
        try:
            if skip_realtime and os.sched_getscheduler(tid) == os.SCHED_FIFO:
                continue
            os.sched_setaffinity(tid, cpus)
        except OSError as exc:  # a thread that ended meanwhile, or a cpuset that refuses
            if not os.path.exists(f"/proc/self/task/{tid}"):
                continue
            failed = f"CPU placement refused ({exc.strerror or exc})"
    return failed


def place_on_loop_cpu() -> str:
    """Move this (servo loop or emulated servos) process onto the loop CPU; returns what
    was done, for the log."""
    plan = cpu_plan()
    return _note(plan.detail if not plan.active
                 else _move_process(plan.loop, skip_realtime=False) or plan.detail)


def place_beside_loop() -> str:
    """Move this (front end or 3D view server) process off the loop CPU; its real-time
    threads, if any, stay where they are. Returns what was done."""
    plan = cpu_plan()
    return _note(plan.detail if not plan.active
                 else _move_process(plan.rest, skip_realtime=True) or plan.detail)


def _note(done: str) -> str:
    global _placed
    _placed = done
    return done


def placement() -> str:
    """What the last placement of this process did, with the CPUs the calling thread may
    use now (for the run log's ``realtime`` event)."""
    now = _fmt(frozenset(os.sched_getaffinity(0))) if hasattr(os, "sched_getaffinity") else "?"
    return f"{_placed or 'not placed'}; this thread may run on CPU {now}"
