"""Design sweeps on Dask: the same table in one process and on a two-worker local cluster; a
worker killed mid-sweep loses no design; Ctrl-C stops a sweep, and the same command finishes
it without computing again what was done."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from spm_console.design.spec import load_spec
from spm_console.design.sweep import SweepProgress, run_sweep
from spm_console.design.table import JOURNAL, load_table
from spm_console.errors import ExitCode
from tests.support.fake_services import tcp_service
from tests.support.paths import ROOT
from tests.support.terminal_helpers import wait_until

AGILE = ROOT / "profiles" / "agile_wrist.toml"


def _spec(tmp_path: Path, count: int, step: float = 10.0) -> Path:
    p = tmp_path / "spec.toml"
    p.write_text(f'[sweep]\nbase_profile = "{AGILE}"\nstep_deg = {step}\n'
                 f"[parameters.alpha1_deg]\nmin = 80.0\nmax = 100.0\ncount = {count}\n"
                 "[parameters.delta_mm]\nmin = 12.0\nmax = 16.0\ncount = 2\n")
    return p


def _comparable(folder: Path) -> str:
    _, cols = load_table(folder)
    return repr({c: v for c, v in cols.items() if c not in ("seconds", "worker")})


@pytest.mark.slow  # a two-worker cluster on both cores (CI runs the slow set)
def test_one_process_and_a_two_worker_cluster_give_the_same_table(tmp_path: Path) -> None:
    spec = load_spec(_spec(tmp_path, 3))
    alone = run_sweep(spec, tmp_path / "alone", workers=0)
    pids: list[int] = []
    pair = run_sweep(spec, tmp_path / "pair", workers=2,
                     on_client=lambda c: pids.extend(c.run(os.getpid).values()))
    assert (alone.computed, pair.computed, pair.workers, len(pids)) == (6, 6, 2, 2)
    assert _comparable(tmp_path / "alone") == _comparable(tmp_path / "pair")
    _, cols = load_table(tmp_path / "pair")
    assert {int(w.split(":")[1]) for w in cols["worker"]} <= set(pids)  # the workers did it


@pytest.mark.slow  # a cluster, a killed worker and its restart (CI runs the slow set)
def test_a_worker_killed_mid_sweep_loses_no_design(tmp_path: Path) -> None:
    spec = load_spec(_spec(tmp_path, 8, step=5.0))
    clients: list[Any] = []
    lost: list[str] = []  # the keys the killed worker was computing

    def progress(p: SweepProgress) -> None:
        if p.computed == 2 and not lost:  # mid-sweep: one worker dies with its task
            client = clients[0]
            addr, pid = next(iter(client.run(os.getpid).items()))
            lost.extend(str(k) for k in client.processing()[addr])
            os.kill(pid, signal.SIGKILL)
            lost.append(str(pid))

    out = run_sweep(spec, tmp_path / "s", workers=2, progress=progress, on_client=clients.append)
    assert len(lost) >= 2 and out.computed == 16 and out.failed == 0
    _, cols = load_table(tmp_path / "s")
    assert cols["index"] == list(range(16)) and all(cols["ok"])
    killed_pid = lost.pop()
    for key in lost:  # each design lost with the worker was run again, by another worker
        row = cols["index"].index(int(key.rsplit("-", 1)[1]))
        assert not cols["worker"][row].endswith(f":{killed_pid}")
    reference = run_sweep(spec, tmp_path / "ref", workers=0)
    assert reference.computed == 16
    assert _comparable(tmp_path / "s") == _comparable(tmp_path / "ref")


@pytest.mark.slow  # two whole commands with their clusters
def test_ctrl_c_stops_the_sweep_and_the_same_command_finishes_it(tmp_path: Path) -> None:
    spec = _spec(tmp_path, 10, step=5.0)
    out = tmp_path / "s"
    cmd = [sys.executable, "-m", "spm_console", "design", "sweep", str(spec), "--out", str(out),
           "--workers", "2", "--json"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)  # its own group: Ctrl-C reaches all of it
    journal = out / JOURNAL
    t_end = time.monotonic() + 120
    while time.monotonic() < t_end and proc.poll() is None:
        if journal.exists() and journal.read_text().count("\n") >= 3:
            break
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == ExitCode.INTERRUPTED, stderr
    assert json.loads(stdout)["ok"] is False and "the same command resumes" in stderr
    assert "Traceback" not in stderr
    before = journal.read_bytes()
    done = before.count(b"\n")
    assert 3 <= done < 20
    second = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert second.returncode == 0, second.stderr
    rec = json.loads(second.stdout)
    assert rec["resumed"] == done and rec["computed"] == 20 - done
    assert journal.read_bytes().startswith(before)  # nothing done was computed again
    _, cols = load_table(out)
    assert cols["index"] == list(range(20))


@pytest.mark.slow  # a whole command
def test_ctrl_c_while_the_cluster_starts_is_not_lost(tmp_path: Path) -> None:
    proc = subprocess.Popen([sys.executable, "-m", "spm_console", "design", "sweep",
                             str(_spec(tmp_path, 3)), "--out", str(tmp_path / "s"), "--workers",
                             "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    time.sleep(1.0)  # the interpreter is up; the cluster is starting or has just started
    os.killpg(proc.pid, signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == ExitCode.INTERRUPTED, stderr
    assert "Traceback" not in stderr


@pytest.fixture
def group_signals_default() -> Iterator[None]:
    """SIGHUP and SIGQUIT at their defaults for the commands a test starts, even when the tests
    run under ``nohup`` or in a shell's background (which ignore them, and the command leaves
    an ignored signal ignored)."""
    old = {sig: signal.signal(sig, signal.SIG_DFL) for sig in (signal.SIGHUP, signal.SIGQUIT)}
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


@pytest.mark.slow  # a whole command with its cluster
@pytest.mark.parametrize("sig", [signal.SIGHUP, signal.SIGQUIT], ids=["hup", "quit"])
@pytest.mark.usefixtures("group_signals_default")
def test_a_hangup_or_quit_to_the_group_stops_the_sweep_without_tracebacks(
        tmp_path: Path, sig: signal.Signals) -> None:
    """The terminal closed (SIGHUP) or Ctrl-\\ (SIGQUIT) reaches every process of the group,
    multiprocessing's resource tracker too: it must survive them (it ignores only SIGINT and
    SIGTERM itself), or its restart prints a KeyError traceback for each of the workers'
    semaphores. The sweep stops with exit 130 and the group is gone."""
    out = tmp_path / "s"
    proc = subprocess.Popen([sys.executable, "-m", "spm_console", "design", "sweep",
                             str(_spec(tmp_path, 10, step=5.0)), "--out", str(out), "--workers",
                             "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    journal = out / JOURNAL
    wait_until(lambda: journal.exists() and journal.read_text().count("\n") >= 2,
               "two designs done", timeout_s=120, proc=proc)  # type: ignore[arg-type]
    os.killpg(proc.pid, sig)
    _, stderr = proc.communicate(timeout=60)  # until every process holding stderr is gone
    assert proc.returncode == ExitCode.INTERRUPTED, stderr
    assert f"sweep stopped by {sig.name}" in stderr and "the same command resumes" in stderr
    for noise in ("Traceback", "KeyError", "resource_tracker"):
        assert noise not in stderr, stderr
    wait_until(lambda: not _group_alive(proc.pid), "the group gone", timeout_s=30)


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def test_no_scheduler_at_the_address_is_a_refusal(tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    from spm_console.cli.main import main
    from spm_console.design import sweep

    monkeypatch.setattr(sweep, "CONNECT_TIMEOUT_S", 1.0)
    rc = main(["design", "sweep", str(_spec(tmp_path, 2)), "--out", str(tmp_path / "s"),
               "--scheduler", "tcp://127.0.0.1:9", "--json"])
    assert rc == ExitCode.BAD_INPUT


@pytest.mark.slow  # a whole command
def test_a_service_that_is_not_dask_is_refused_without_a_traceback(tmp_path: Path) -> None:
    """A service at the address that sends garbage (a length no machine holds): refused by the
    probe, exit 4, and no Dask client is left to fail its closing at exit."""
    with tcp_service("huge") as port:
        proc = subprocess.run([sys.executable, "-m", "spm_console", "design", "sweep",
                               str(_spec(tmp_path, 2)), "--out", str(tmp_path / "s"),
                               "--scheduler", f"tcp://127.0.0.1:{port}"],
                              capture_output=True, text=True, timeout=120)
    assert proc.returncode == ExitCode.BAD_INPUT, proc.stderr
    assert "not a Dask scheduler" in proc.stderr and "Traceback" not in proc.stderr
    assert not (tmp_path / "s").exists()




@pytest.mark.slow  # a scheduler and a worker started as a lab would, then a sweep on them
def test_a_sweep_runs_on_an_existing_cluster(tmp_path: Path) -> None:
    from spm_console.cli.main import main

    dask = Path(sys.executable).with_name("dask")
    where = tmp_path / "scheduler.json"  # the scheduler picks a free port and writes it here
    logs = [open(tmp_path / f"{n}.log", "w") for n in ("scheduler", "worker")]  # noqa: SIM115
    procs = [subprocess.Popen([str(dask), "scheduler", "--host", "127.0.0.1", "--port", "0",
                               "--no-dashboard", "--scheduler-file", str(where)],
                              stdout=logs[0], stderr=logs[0])]
    try:
        t_end = time.monotonic() + 60
        address = ""
        while not address and time.monotonic() < t_end:
            time.sleep(0.1)
            try:
                address = json.loads(where.read_text())["address"]
            except (OSError, ValueError, KeyError):
                continue  # not written yet, or not whole yet
        procs.append(subprocess.Popen([str(dask), "worker", address, "--nworkers", "2",
                                       "--nthreads", "1", "--no-dashboard"],
                                      stdout=logs[1], stderr=logs[1]))
        spec = load_spec(_spec(tmp_path, 2))
        rc = main(["design", "sweep", str(_spec(tmp_path, 2)), "--out", str(tmp_path / "far"),
                   "--scheduler", address])
        assert rc == 0
        run_sweep(spec, tmp_path / "near", workers=0)
        assert _comparable(tmp_path / "far") == _comparable(tmp_path / "near")
        # the scheduler goes away mid-sweep: exit 12, what is done is kept
        longer = subprocess.Popen([sys.executable, "-m", "spm_console", "design", "sweep",
                                   str(_spec(tmp_path, 12, step=5.0)), "--out",
                                   str(tmp_path / "cut"), "--scheduler", address],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        journal = tmp_path / "cut" / JOURNAL
        while time.monotonic() < t_end + 120 and longer.poll() is None and not (
                journal.exists() and journal.read_text().count("\n") >= 2):
            time.sleep(0.05)
        procs[0].kill()
        _, stderr = longer.communicate(timeout=120)
        assert longer.returncode == ExitCode.CLUSTER_LOST, stderr
        assert "Traceback" not in stderr and "the same command resumes" in stderr
        assert len(load_table(tmp_path / "cut")[1]["index"]) >= 2
    finally:
        for p in procs:
            p.terminate()
        for p in procs:
            p.wait(timeout=30)
        for f in logs:
            f.close()
