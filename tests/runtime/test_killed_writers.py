"""A writer killed mid-write (SIGKILL) leaves whole files behind: the workspace cache and run logs."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from spm_console.motion.logs.runlog import (
    COLUMNS,
    FLUSH_EVERY,
    load_run,
)
from spm_console.store import workspace_cache as wc
from spm_console.store.workspace_cache import save
from tests.support.ws_helpers import ROOT, agile_profile, coarse_workspace, with_step
from tests.unit.motion.test_runlog import WRITER
from tests.unit.store.test_workspace_cache import _WRITER


def test_kill_during_writes_leaves_a_whole_file(tmp_path: Path) -> None:
    """SIGKILL a process that rewrites the cache in a loop: the file at the final path
    is always a complete, loadable cache (or absent), never half-written."""
    path = tmp_path / "workspace-x.npz"
    save(coarse_workspace(), path, "key")
    proc = subprocess.Popen([sys.executable, "-c", _WRITER.format(root=str(ROOT), path=str(path))],
                            stdout=subprocess.PIPE, cwd=ROOT)
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == b"ready"
    rng = np.random.default_rng(0)
    time.sleep(0.3 + float(rng.uniform(0, 0.3)))
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    prof = with_step(agile_profile(), 5.0)
    ws = wc.load(path, prof, "key")
    assert ws.counts() == coarse_workspace().counts()
    # leftover temp files are never taken for the cache
    assert all(p.suffix == ".tmp" for p in tmp_path.iterdir() if p != path)

def test_sigkill_leaves_a_readable_log(tmp_path: Path) -> None:
    proc = subprocess.Popen([sys.executable, "-c", WRITER, str(tmp_path)],
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    path = Path(proc.stdout.readline().strip())
    assert proc.stdout.readline().strip() == "flushed"
    time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)
    assert proc.returncode == -signal.SIGKILL
    run = load_run(path)
    assert run.meta["outcome"] == "killed"  # never finished, and its process is gone
    assert json.loads((path / "meta.json").read_text())["outcome"] == "running"  # as left
    assert run.rows >= 36 - FLUSH_EVERY  # everything up to the last flush
    ks = run.columns["k"]
    assert np.array_equal(ks, np.arange(len(ks)))  # complete rows, in order, no holes
    assert np.allclose(run.vec("meas")[:, 0], ks)
    assert run.events and all(e["event"] == "tick" for e in run.events)
    assert list(COLUMNS) == (path / "samples.csv").read_text().splitlines()[0].split(",")
