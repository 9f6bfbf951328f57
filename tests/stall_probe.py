"""Host stall probe (run by ``tests/host_stalls.py``, one process per CPU): how late the host
wakes a top-priority thread pinned to one CPU.

``python tests/stall_probe.py CPU``: pins itself to CPU, asks for SCHED_FIFO above every
thread of the console (the emulated servos run at 45), then sleeps ``PERIOD_S`` at a time
and prints one line per wake-up that came at least ``REPORT_MS`` late:
``<CLOCK_MONOTONIC at the wake-up, s> <lateness, ms>``. The first line says what scheduling
it got. At that priority nothing of ours can delay it: a late wake-up is the host (a
virtual CPU not run by the hypervisor, the kernel). It ends when its parent does.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time

PERIOD_S = 0.002
REPORT_MS = 2.0
PRIORITY = 50


def main() -> None:
    cpu = int(sys.argv[1])
    parent = os.getppid()
    os.sched_setaffinity(0, {cpu})
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(PRIORITY))
        policy = f"SCHED_FIFO {PRIORITY}"
    except OSError as exc:
        policy = f"normal priority (SCHED_FIFO refused: {exc.strerror})"
    print(f"# cpu {cpu}: {policy}", flush=True)
    prev = time.monotonic()
    n = 0
    while True:
        time.sleep(PERIOD_S)
        now = time.monotonic()
        late_ms = (now - prev - PERIOD_S) * 1e3
        if late_ms >= REPORT_MS:
            print(f"{now:.6f} {late_ms:.3f}", flush=True)
        prev = now
        n += 1
        if n % 250 == 0 and os.getppid() != parent:
            return


if __name__ == "__main__":
    with contextlib.suppress(BrokenPipeError, KeyboardInterrupt):
        main()
