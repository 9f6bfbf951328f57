"""``latency`` and :mod:`spm_console.system.host_latency`: statistics, verdict, bounds, and a stall
made on purpose (SIGSTOP) that the measurement must see."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from spm_console.cli.main import main
from spm_console.cli.tools.latency import VERDICTS, verdict
from spm_console.errors import ExitCode
from spm_console.system.host_latency import THRESHOLDS_MS, measured_meanwhile, summarize

pytestmark = pytest.mark.realtime  # about the wall clock (see tests/conftest.py)


def test_summary_counts_each_threshold_and_the_percentiles() -> None:
    late = np.array([0.0] * 96 + [1.0, 2.5, 4.0, 30.0])
    s = summarize(0, "SCHED_FIFO priority 40", 2.0, 0.001, late)
    assert s.wakeups == 100 and s.max_ms == 30.0 and s.p50_ms == 0.0
    assert dict(s.late) == {1.0: 4, 2.0: 3, 4.0: 2, 10.0: 1, 20.0: 1, 50.0: 0}
    assert s.per_minute(4.0) == pytest.approx(60.0)  # 2 in 2 s
    assert 4.0 <= s.p99_ms <= 30.0
    empty = summarize(1, "normal", 1.0, 0.001, np.array([]))
    assert empty.wakeups == 0 and np.isnan(empty.max_ms) and all(n == 0 for _, n in empty.late)


def test_verdict_compares_the_longest_stall_with_timeout_and_window() -> None:
    def cpu(max_ms: float):  # type: ignore[no-untyped-def]
        return summarize(0, "x", 1.0, 0.001, np.array([0.1, max_ms]))

    assert verdict([cpu(1.0), cpu(3.9)], 4.0, 60.0) == "fit"
    assert verdict([cpu(1.0), cpu(4.0)], 4.0, 60.0) == "late_reads"
    assert verdict([cpu(61.0), cpu(1.0)], 4.0, 60.0) == "comm_loss_risk"


def test_latency_command_reports_every_cpu_against_the_profile(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["latency", "--seconds", "0.5", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["ok"] and out["verdict"] in VERDICTS
    assert out["reply_timeout_ms"] == 4.0 and out["comm_loss_window_ms"] == 60.0
    cpus = out["cpus"]
    assert sorted(c["cpu"] for c in cpus) == sorted(os.sched_getaffinity(0))
    for c in cpus:
        assert 0 < c["wakeups"] <= 0.5 / 0.001 + 1
        counts = [n for _, n in c["late"]]
        assert [t for t, _ in c["late"]] == sorted({*THRESHOLDS_MS, 4.0, 60.0})
        assert counts == sorted(counts, reverse=True) and counts[0] <= c["wakeups"]
        assert c["p50_ms"] <= c["p99_ms"] <= c["max_ms"]


@pytest.mark.parametrize("seconds", ["0", "-1", "601", "nan", "inf"])
def test_latency_refuses_an_unbounded_duration(capsys: pytest.CaptureFixture[str], seconds: str) -> None:
    code = main(["latency", "--seconds", seconds, "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == ExitCode.BAD_INPUT and not out["ok"] and "--seconds" in out["error"]


def test_a_probe_stopped_for_150_ms_reports_a_stall_of_at_least_that() -> None:
    """The stream mode (the test suite's stall probes) against a stall made on purpose."""
    cpu = min(os.sched_getaffinity(0))
    p = subprocess.Popen([sys.executable, "-m", "spm_console.system.host_latency", "--stream", "--cpu", str(cpu),
                          "--report-ms", "50"], stdout=subprocess.PIPE, text=True)
    assert p.stdout is not None
    guard = threading.Timer(60.0, p.kill)  # a probe that never reports: EOF, and the test fails
    guard.start()
    try:
        assert p.stdout.readline().startswith(f"# cpu {cpu}: ")  # measuring from now on
        time.sleep(0.1)
        os.kill(p.pid, signal.SIGSTOP)
        time.sleep(0.15)
        os.kill(p.pid, signal.SIGCONT)
        t, late_ms = (float(x) for x in p.stdout.readline().split())  # blocks until reported
    finally:
        guard.cancel()
        p.kill()
        p.wait()
    assert late_ms >= 150.0 - 1.0  # the stop, less at most one 1 ms period
    assert abs(time.monotonic() - t) < 60.0  # stamped on the shared monotonic clock


def test_measured_meanwhile_covers_the_block_on_every_cpu() -> None:
    t0 = time.monotonic()
    with measured_meanwhile() as cpus:
        assert cpus == []  # filled when the block ends
        time.sleep(0.5)
    block = time.monotonic() - t0
    assert sorted(c.cpu for c in cpus) == sorted(os.sched_getaffinity(0))
    for c in cpus:
        # from the probe's first sleep (after its start-up) to the line that ended it
        assert 0.0 < c.seconds <= block and c.wakeups > 0
        assert np.isnan(c.steal_ms) or c.steal_ms >= 0.0
