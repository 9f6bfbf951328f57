"""Run logs: round trip, outcome rewrite, truncated lines, and a SIGKILLed writer."""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from spm_console.config.schema import Profile
from spm_console.errors import BadInputError
from spm_console.motion.logs import runlog
from spm_console.motion.logs.procid import current_process, writer_alive
from spm_console.motion.logs.profile_record import same_profile
from spm_console.motion.logs.runlog import (
    FLUSH_EVERY,
    LOGS_ENV,
    META_ROOM,
    RunLog,
    list_runs,
    load_run,
    logs_root,
)
from spm_console.motion.sample import Sample


def _sample(k: int, ok: bool = True) -> Sample:
    base = 100.0 + k
    return Sample(
        t=k * 0.02, k=k, phase="plan", reference_deg=np.array([base, base + 1, base + 2]),
        measured_deg=np.array([base, base, base]) if ok else np.full(3, np.nan),
        predicted_deg=np.full(3, base + 0.1), predicted_velocity_degps=np.full(3, 5.0),
        filtered_deg=np.full(3, base + 0.05), velocity_degps=np.array([1.0, 2.0, 3.0]),
        fd_velocity_degps=np.full(3, 4.0), tracking_error_deg=0.1 if ok else float("nan"),
        bus_s=0.0012, late_s=0.0001, retries=0 if ok else 2,
    )

def test_round_trip(tmp_path: Path) -> None:
    log = RunLog.create("execute", "agile_wrist", "abc123", [{"kind": "mvn", "N": 3}],
                        root=tmp_path, flush_every=2)
    for k in range(4):
        log.sample(_sample(k, ok=k != 2))
    log.event("comm_retry", 0.04, op="read", error="timeout")
    meta0 = json.loads((log.path / "meta.json").read_text())
    assert meta0["outcome"] == "running" and meta0["profile"]["hash"] == "abc123"
    log.finish("completed", 0, "done", {"samples": 4})
    run = load_run(log.path)
    assert run.rows == 4 and not run.truncated
    assert run.meta["outcome"] == "completed" and run.meta["exit_code"] == 0
    assert run.meta["versions"]["numpy"] == np.__version__
    assert "start_time" in run.meta and run.meta["end_time"]
    assert np.allclose(run.vec("ref")[3], [103, 104, 105])
    assert np.isnan(run.vec("meas")[2]).all() and run.columns["retries"][2] == 2
    assert np.allclose(run.vec("vel")[0], [1, 2, 3])
    assert run.events == [{"t": 0.04, "event": "comm_retry", "op": "read", "error": "timeout"}]
    assert run.phase == ["plan"] * 4
    assert [r.name for r in list_runs(tmp_path)] == [log.path.name]
    assert load_run(log.path.name, root=tmp_path).path == log.path

def test_truncated_last_line_is_dropped(tmp_path: Path) -> None:
    log = RunLog.create("execute", "p", "h", [], root=tmp_path)
    for k in range(3):
        log.sample(_sample(k))
    log.close()
    with (log.path / "samples.csv").open("a") as fh:
        fh.write("0.06,3,plan,103")  # killed mid-row
    with (log.path / "events.jsonl").open("a") as fh:
        fh.write('{"t": 0.1, "eve')
    run = load_run(log.path)
    assert run.rows == 3 and run.truncated
    assert run.meta["outcome"] == "running"

def test_unique_folders_and_env_root(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(LOGS_ENV, str(tmp_path / "elsewhere"))
    assert logs_root() == tmp_path / "elsewhere"
    a = RunLog.create("home", "p", "h", [])
    b = RunLog.create("home", "p", "h", [])
    assert a.path != b.path and a.path.parent == tmp_path / "elsewhere"
    a.close()
    b.close()
    with pytest.raises(BadInputError, match="no run"):
        load_run("nope")

WRITER = """
import sys, time, numpy as np
from spm_console.motion.logs.runlog import RunLog
from spm_console.motion.sample import Sample
log = RunLog.create("execute", "p", "h", [], root=sys.argv[1])
print(log.path, flush=True)
k = 0
while True:
    v = np.full(3, float(k))
    log.sample(Sample(t=k * 0.02, k=k, phase="plan", reference_deg=v, measured_deg=v,
        predicted_deg=v, predicted_velocity_degps=v, filtered_deg=v, velocity_degps=v,
        fd_velocity_degps=v, tracking_error_deg=0.0, bus_s=0.001, late_s=0.0))
    if k % 7 == 0:
        log.event("tick", k * 0.02, k=k)
    if k == 35:
        print("flushed", flush=True)
    k += 1
    time.sleep(0.002)
"""

def test_rows_reach_the_os_every_few_samples(tmp_path: Path) -> None:
    assert 1 <= FLUSH_EVERY <= 3  # a SIGKILL loses at most FLUSH_EVERY - 1 logged rows
    log = RunLog.create("execute", "p", "h", [], root=tmp_path)
    csv_path = log.path / "samples.csv"
    for k in range(2 * FLUSH_EVERY):
        log.sample(_sample(k))
        on_disk = csv_path.read_text().count("\n") - 1  # what another process sees
        assert on_disk == (k + 1) // FLUSH_EVERY * FLUSH_EVERY
    log.close()

def test_a_running_log_is_killed_only_when_its_own_process_is_gone(tmp_path: Path) -> None:
    me = current_process()
    assert me["pid"] == os.getpid() and writer_alive(me) is True
    log = RunLog.create("execute", "p", "h", [], root=tmp_path)
    assert log.meta["process"] == me
    assert [r.meta["outcome"] for r in list_runs(tmp_path)] == ["running"]  # we are alive

    def runs_with(process: object) -> str:
        meta = json.loads((log.path / "meta.json").read_text())
        (log.path / "meta.json").write_text(json.dumps({**meta, "process": process}))
        return str(list_runs(tmp_path)[0].meta["outcome"])

    if me["start_ticks"] is not None:  # the pid reused by a later process: not ours
        assert runs_with({**me, "start_ticks": me["start_ticks"] + 1}) == "killed"
    if me["boot_id"] is not None:  # written before a reboot
        assert runs_with({**me, "boot_id": "another-boot"}) == "killed"
    assert runs_with({**me, "host": "another-host"}) == "running"  # cannot tell: as written
    assert runs_with(None) == "running"  # logs written before the process was recorded
    assert runs_with({**me, "pid": 0}) == "running"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    assert runs_with({**me, "pid": int(dead.stdout)}) == "killed"
    log.close()

def test_runs_started_within_one_second_are_listed_in_start_order(tmp_path: Path) -> None:
    """An ``execute`` homes first: both folders share the second; 'last' is the execution."""
    a = RunLog.create("home", "p", "h", [], root=tmp_path)
    b = RunLog.create("execute", "p", "h", [], root=tmp_path)
    a.finish("completed", 0, "", {})
    b.finish("completed", 0, "", {})
    if a.path.name[:15] == b.path.name[:15]:  # same second (almost always)
        assert a.path.name > b.path.name  # "home" sorts after "execute" by name alone
    assert [r.meta["kind"] for r in list_runs(tmp_path)] == ["home", "execute"]
    assert load_run("last", tmp_path).meta["kind"] == "execute"


def test_a_log_folder_that_cannot_take_a_run_is_refused_before_anything(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """An existing folder this process may not write (EACCES, EROFS, EPERM all look alike
    here), or one whose disk is full: a bad-input refusal, and no half-made run folder."""
    real_mkdir = Path.mkdir

    def denied(self: Path, *a: object, **k: object) -> None:
        if self.parent == tmp_path:
            raise PermissionError(errno.EACCES, "Permission denied")
        real_mkdir(self, *a, **k)  # type: ignore[arg-type]

    monkeypatch.setattr(Path, "mkdir", denied)
    with pytest.raises(BadInputError, match="cannot create a run folder in it"):
        RunLog.create("execute", "agile_wrist", "abc", [], root=tmp_path)
    monkeypatch.setattr(Path, "mkdir", real_mkdir)
    real_open = Path.open

    def full(self: Path, *a: object, **k: object):  # type: ignore[no-untyped-def]
        if self.name == "events.jsonl":
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_open(self, *a, **k)  # type: ignore[arg-type]

    monkeypatch.setattr(Path, "open", full)
    with pytest.raises(BadInputError, match="No space left on device"):
        RunLog.create("execute", "agile_wrist", "abc", [], root=tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_the_outcome_is_written_over_meta_json_when_the_disk_is_full(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """meta.json is made with room for its outcome (META_ROOM bytes): when no new file can be
    made (ENOSPC), the outcome is written over it in place, and it stays valid JSON."""
    log = RunLog.create("execute", "agile_wrist", "abc", [], root=tmp_path)
    meta = log.path / "meta.json"
    assert meta.stat().st_size == META_ROOM
    log.sample(_sample(0))

    def no_space(*a: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(runlog.os, "replace", no_space)
    log.finish("completed", 0, "done", {"samples": 1})
    assert meta.stat().st_size == META_ROOM
    run = load_run(log.path)
    assert run.meta["outcome"] == "completed" and run.rows == 1
    assert not list(log.path.glob("*.tmp"))


def test_a_run_on_the_physical_twin_is_logged_with_its_own_profile(agile: Profile) -> None:
    """``--plant physical`` (and the console's twin) sets ``[plant] model`` for one run: its
    log's hash is that of the copy, and ``logs export`` said the profile had been edited. The
    emulated plant is a choice of emulator; any other change is an edit."""
    physical = agile.model_copy(update={"plant": agile.plant.model_copy(update={"model": "physical"})})
    assert physical.digest() != agile.digest()
    for logged in (agile, physical):
        assert same_profile({"hash": logged.digest()}, agile)
        assert same_profile({"hash": logged.digest()}, physical)
    edited = agile.model_copy(update={"servo": agile.servo.model_copy(update={"ts_s": 0.01})})
    assert not same_profile({"hash": edited.digest()}, agile)
    assert not same_profile({}, agile)


def test_a_run_without_samples_is_shown_and_no_empty_plot_is_drawn(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A commissioning's run holds events only: ``logs show --plot`` says there is nothing to
    draw instead of writing six empty axes."""
    from spm_console.cli.main import main

    log = RunLog.create("commission", "agile_wrist", "abc123", [], root=tmp_path)
    log.event("nudge", 0.1, ids=[1, 2, 3])
    log.finish("completed", 0, "commissioned", {})
    png = tmp_path / "f.png"
    assert main(["logs", "--logs", str(tmp_path), "show", log.path.name, "--plot", str(png),
                 "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["plot"] is None and not png.exists()
    assert main(["logs", "--logs", str(tmp_path), "show", log.path.name, "--plot", str(png)]) == 0
    assert "the run has no samples to draw" in capsys.readouterr().out
