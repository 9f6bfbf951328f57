"""CPU placement: the servo loop's and the emulated servos' processes on one CPU, the
console's own process (and the 3D view's server) on the others (spm_console.system.cpus)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from spm_console.system.cpus import ENV_CHOICE, ENV_SET, cpu_plan

pytestmark = pytest.mark.realtime  # about the wall clock (see tests/conftest.py)


@pytest.mark.parametrize(("allowed", "choice", "loop", "rest"), [
    ("0,1", "auto", {1}, {0}),
    ("0,1,2,3", "auto", {3}, {0, 1, 2}),
    ("0,1", "0", {0}, {1}),
    ("2,5", "auto", {5}, {2}),
])
def test_the_loop_gets_one_cpu_and_the_console_the_rest(
        monkeypatch: pytest.MonkeyPatch, allowed: str, choice: str, loop: set[int],
        rest: set[int]) -> None:
    monkeypatch.setenv(ENV_SET, allowed)
    monkeypatch.setenv(ENV_CHOICE, choice)
    plan = cpu_plan()
    assert plan.active and plan.loop == loop and plan.rest == rest
    assert f"CPU {min(loop)}" in plan.detail


@pytest.mark.parametrize(("allowed", "choice", "why"), [
    ("0,1", "off", "asks for it"),
    ("0,1", "", "asks for it"),
    ("3", "auto", "1 CPU allowed"),
    ("0,1", "7", "CPU 7 is not allowed"),
    ("0,1", "fast", "not auto, off or a CPU"),
])
def test_no_placement_says_why(monkeypatch: pytest.MonkeyPatch, allowed: str, choice: str,
                               why: str) -> None:
    monkeypatch.setenv(ENV_SET, allowed)
    monkeypatch.setenv(ENV_CHOICE, choice)
    plan = cpu_plan()
    assert not plan.active and why in plan.detail


_PROBE = textwrap.dedent("""
    import json, os, sys
    from spm_console.config.load import load_profile
    from spm_console.services.session import Session

    def allowed(pid):
        with open(f"/proc/{pid}/status") as f:
            line = next(x for x in f if x.startswith("Cpus_allowed_list"))
        return line.split()[1]

    s = Session(load_profile(sys.argv[1]), sim=True, emulator_process=True)
    s.connect()
    try:
        tasks = os.listdir("/proc/self/task")
        print(json.dumps({"loop": allowed(s.bus.process.pid), "emulator": allowed(s.emulator.pid),
                          "console": sorted({allowed(f"self/task/{t}") for t in tasks}),
                          "said": s.bus_state.cpu_placement}))
    finally:
        s.disconnect()
""")


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs two allowed CPUs")
def test_a_connected_console_keeps_off_the_loops_cpu(root: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(ENV_CHOICE, "auto")  # the children inherit it
    plan = cpu_plan()  # this process may have been placed already: the set it started with
    loop = str(min(plan.loop))
    out = subprocess.run([sys.executable, "-c", _PROBE, str(root / "profiles" / "agile_wrist.toml")],
                         capture_output=True, text=True, timeout=120, check=True).stdout
    seen = json.loads(out.splitlines()[-1])
    assert seen["loop"] == loop and seen["emulator"] == loop, seen
    # the console's threads (its in-process emulator would be the only exception) beside it
    assert loop not in ",".join(seen["console"]).split(","), seen
    assert f"on CPU {loop}" in seen["said"], seen
