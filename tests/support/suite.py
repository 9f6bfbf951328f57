"""``make test``: the whole suite (slow tests deselected) in one wall-clock stretch.

The tests of the real-time loop, the console and whole commands (``tests/runtime``,
``tests/tui``, ``tests/e2e``) spend about a third of their time waiting on motions that run
in real time; the unit tests (``tests/unit``: pure computation) run beside them at the
idle scheduling class (``SCHED_IDLE``, else the lowest ``nice``), so they take only the CPU
time nothing else wants and yield at once to the emulated servos (at the lowest ``nice``
instead, their replies came late: two failures in one run). Their output is printed
after the other run's; the exit status is the first failing run's.

Usage: ``python -m tests.support.suite [PYTEST ARGS FOR BOTH RUNS]``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile

UNIT = ["tests/unit", "-n", "auto"]
RUNTIME = ["tests/runtime", "tests/tui", "tests/e2e", "-n", "2", "--dist", "loadgroup"]


def _idle() -> None:
    """In the unit run's process, before it starts: the idle scheduling class (inherited by
    its pytest-xdist workers)."""
    try:
        os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
    except (AttributeError, OSError):  # not Linux, or not allowed: the lowest nice instead
        os.nice(19)


def main(argv: list[str]) -> int:
    pytest = [sys.executable, "-m", "pytest"]
    env = {**os.environ, "SPM_TESTS_HOST_STALLS": "0"}
    with tempfile.TemporaryFile("w+b") as out:
        unit = subprocess.Popen([*pytest, *UNIT, *argv], stdout=out, stderr=subprocess.STDOUT,
                                env=env, preexec_fn=_idle)
        try:
            runtime = subprocess.call([*pytest, *RUNTIME, *argv])
            unit_code = unit.wait()
        finally:
            if unit.poll() is None:  # interrupted: the unit run goes too
                unit.terminate()
                unit.wait()
        out.seek(0)
        sys.stdout.flush()
        print("\n===== tests/unit (run beside the above at idle priority) =====", flush=True)
        sys.stdout.buffer.write(out.read())
        sys.stdout.flush()
    return runtime or unit_code


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
