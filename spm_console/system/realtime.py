"""Real-time scheduling for the threads that keep time: the servo loop and the emulated bus.

:func:`request_realtime` asks the kernel to run the *calling thread* under SCHED_FIFO at a
given priority (Linux scheduling is per thread); when that is not permitted it asks for a
raised nice value instead, and otherwise leaves the thread as it is. Every outcome is
returned as an :class:`RtGrant` so the caller can say in its log (and the console) what
it got. :func:`release_realtime` gives the thread back its normal policy.

The bounded work of a FIFO thread (one bus transaction, a few hundred microseconds, then a
sleep until the next period) cannot starve the machine; the kernel's RT throttling (95 % by
default) bounds it anyway. ``SPM_CONSOLE_REALTIME=0`` in the environment switches it off.
"""

from __future__ import annotations

import functools
import os
import threading
from dataclasses import dataclass

from spm_console.system.env import switched_off

#: Environment variable: ``0`` (or ``no``, ``off``, ``false``) switches real-time scheduling off.
ENV_REALTIME = "SPM_CONSOLE_REALTIME"
#: SCHED_FIFO priorities (1..99): the emulated servos above the loop that talks to them.
LOOP_PRIORITY = 40
EMULATOR_PRIORITY = 45
#: The other threads of the loop's (and the emulator's) process. They hold that
#: interpreter's GIL at times (reading the client's pipe, shipping telemetry, the deadman);
#: at normal priority a busy machine preempts them *while they hold it*, and the loop waits
#: for the GIL behind them (priority inversion: 10-20 ms stalls with one CPU-bound process
#: per core). Real-time below the loop, they run their short work and release it.
HELPER_PRIORITY = 30
#: GIL switch interval of the processes that run the servo loop or the emulated servos, s:
#: a thread that wants the GIL waits at most about this long for the holder to let it go
#: (CPython's default, 5 ms, is a quarter of a servo period).
GIL_SWITCH_S = 0.0005
#: Nice value asked for when SCHED_FIFO is refused.
FALLBACK_NICE = -10


@dataclass(frozen=True)
class RtGrant:
    """What the calling thread got."""

    policy: str
    """"SCHED_FIFO", "nice", or "normal"."""
    detail: str
    """E.g. "SCHED_FIFO priority 40", or why it could not be had."""

    @property
    def realtime(self) -> bool:
        return self.policy == "SCHED_FIFO"


def _disabled() -> bool:
    return switched_off(ENV_REALTIME)


def request_realtime(priority: int) -> RtGrant:
    """SCHED_FIFO at ``priority`` for the calling thread, else a raised nice value."""
    if _disabled():
        return RtGrant("normal", f"real-time scheduling switched off ({ENV_REALTIME}=0)")
    if not hasattr(os, "sched_setscheduler"):
        return RtGrant("normal", "this platform has no sched_setscheduler")
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        return RtGrant("SCHED_FIFO", f"SCHED_FIFO priority {priority}")
    except OSError as exc:
        refused = f"SCHED_FIFO refused ({exc.strerror or exc})"
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), FALLBACK_NICE)
        return RtGrant("nice", f"{refused}; nice {FALLBACK_NICE}")
    except OSError as exc:
        return RtGrant("normal", f"{refused}; raising the priority refused too "
                                 f"({exc.strerror or exc}): timing may suffer under load")


def release_realtime(grant: RtGrant) -> None:
    """Back to SCHED_OTHER / nice 0 for the calling thread (after :func:`request_realtime`)."""
    try:
        if grant.policy == "SCHED_FIFO":
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        elif grant.policy == "nice":
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), 0)
    except OSError:
        pass  # lowering our own priority back can only fail if the thread is gone


def normal_priority() -> None:
    """SCHED_OTHER at nice 0 for the calling thread, whatever it inherited (a thread started
    by a real-time thread inherits its policy): for work that may take long, such as loading
    or building a workspace."""
    release_realtime(RtGrant("SCHED_FIFO", ""))
    release_realtime(RtGrant("nice", ""))


def quick_gil_handoff() -> float:
    """Set this process's GIL switch interval to :data:`GIL_SWITCH_S`; returns the old one."""
    import sys

    old = sys.getswitchinterval()
    sys.setswitchinterval(GIL_SWITCH_S)
    return old


@functools.cache
def kernel_preemption() -> str:
    """The running kernel's preemption model, as far as this process can tell.

    Real-time priority bounds how long a woken thread waits for *other threads*; a kernel
    built without full preemption (``PREEMPT_NONE``/``VOLUNTARY``) can still hold a CPU in
    a system call for milliseconds before the woken loop runs. Read from the scheduler's
    debugfs file when it is readable (PREEMPT_DYNAMIC kernels switch at run time), else
    from the kernel's build configuration; "unknown" when neither says.
    """
    try:
        with open("/sys/kernel/debug/sched/preempt", encoding="ascii") as f:
            modes = f.read().split()
        current = next((m.strip("()") for m in modes if m.startswith("(")), "")
        if current:
            return f"{current} (set at run time)"
    except OSError:
        pass
    try:
        import gzip

        with gzip.open("/proc/config.gz", "rt", encoding="ascii") as f:
            config = f.read()
    except OSError:
        return "unknown"
    dynamic = "\nCONFIG_PREEMPT_DYNAMIC=y" in config
    for option, name in (("CONFIG_PREEMPT_RT=y", "full real-time (PREEMPT_RT)"),
                         ("CONFIG_PREEMPT=y", "full"), ("CONFIG_PREEMPT_LAZY=y", "lazy"),
                         ("CONFIG_PREEMPT_VOLUNTARY=y", "voluntary"),
                         ("CONFIG_PREEMPT_NONE=y", "none")):
        if f"\n{option}" in config:
            return name + (" (boot default of a PREEMPT_DYNAMIC kernel)" if dynamic else "")
    return "unknown"
