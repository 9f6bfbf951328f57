"""Shared fixtures. Tests run from the project root (profiles/ is relative to it)."""

from __future__ import annotations

import gc
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
os.chdir(ROOT)

# Tests never touch the operator's cache (~/.cache/spm_console) or the project's logs/:
# one scratch directory per test session (subprocesses inherit it).
_SCRATCH = Path(tempfile.mkdtemp(prefix="spm-tests-"))
os.environ.setdefault("SPM_CONSOLE_CACHE", str(_SCRATCH / "cache"))
os.environ.setdefault("SPM_CONSOLE_LOGS", str(_SCRATCH / "logs"))
# the console remembers form values per profile: never in the tester's own ~/.config
os.environ["SPM_CONSOLE_CONFIG"] = str(_SCRATCH / "config")
# Motion processes fork from a warm start of each front end's own, which ends with it: the
# resident one would outlive the suite (tests/runtime/test_resident.py starts its own, in a
# private folder, and ends it).
os.environ.setdefault("SPM_CONSOLE_WARM_START", "command")
# Motions on the emulated bus run in simulated time (spm_console.system.simclock): the servo
# loop, the bus and the emulated wrist in lockstep, as fast as computed and the same every
# run. Tests about real time take the wall clock (``real_clock``, marked ``realtime``); tests
# that act while a motion runs pace it at real time (``paced_clock``).
os.environ.setdefault("SPM_CONSOLE_CLOCK", "simulated")
# NumPy's and SciPy's OpenBLAS on one thread in every test process and the processes they
# start (set before anything imports NumPy). Each xdist worker would otherwise start a BLAS
# thread per core, and on two cores the workers' idle BLAS threads spin against the other
# worker's work: the unit tests took 77 s (143 CPU-s) on two workers, 60 s (109 CPU-s) on one
# BLAS thread each. No test's matrices are large enough to gain from a second BLAS thread.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# Property tests draw the same examples on every run and machine (a failure found once is
# found again, and CI cannot fail on a draw the last run did not make); set
# HYPOTHESIS_PROFILE=explore to search with fresh random examples instead. No example has a
# deadline: a test asserts no timing (the unit tests of `make test` run at idle priority).
from hypothesis import settings as _hypothesis_settings  # noqa: E402

_hypothesis_settings.register_profile("suite", derandomize=True, database=None, deadline=None)
_hypothesis_settings.register_profile("explore", derandomize=False, database=None, deadline=None)
_hypothesis_settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "suite"))


def pytest_configure(config: pytest.Config) -> None:
    """Host stall probes and the retake rule of ``tests/support/host_stalls.py`` (off with
    ``SPM_TESTS_HOST_STALLS=0``: every failure is then final)."""
    from tests.support.host_stalls import MAX_SUITE_RERUNS, HostStalls, WorkerStallReports

    if os.environ.get("SPM_TESTS_HOST_STALLS", "1") == "0":
        return
    if getattr(config.option, "numprocesses", None) and "PYTEST_XDIST_WORKER" not in os.environ:
        # the controller of a parallel run runs no test: its workers probe and report to it
        config.pluginmanager.register(WorkerStallReports(), "spm_host_stall_reports")
        return
    if config.option.max_suite_reruns is None:
        config.option.max_suite_reruns = MAX_SUITE_RERUNS
    stalls = HostStalls()
    config.pluginmanager.register(stalls, "spm_host_stalls")
    stalls.start()


@pytest.hookimpl(tryfirst=True)  # before pytest-xdist reads the groups
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """For a parallel run (``--dist loadgroup``): each test module is a group of its own (its
    module-scoped fixtures are built once); the tests about real time (marked ``realtime``)
    all go to one group, one at a time, so two real-time runs never compete (``make test``
    leaves them out: ``make test-realtime`` runs them on their own)."""
    for item in items:
        parts = Path(str(item.fspath)).relative_to(ROOT).parts
        if item.get_closest_marker("realtime") is not None:
            item.add_marker(pytest.mark.xdist_group("realtime"))
        elif len(parts) > 2 and parts[1] in ("runtime", "e2e", "tui"):
            item.add_marker(pytest.mark.xdist_group(parts[-1]))


@pytest.fixture
def real_clock(monkeypatch: pytest.MonkeyPatch) -> None:
    """Motions on the emulated bus in real time (the wall clock), for this test and the
    processes it starts."""
    monkeypatch.setenv("SPM_CONSOLE_CLOCK", "real")


@pytest.fixture
def paced_clock(monkeypatch: pytest.MonkeyPatch) -> None:
    """Motions on the emulated bus in simulated time paced at real time: a test that acts
    while the wrist moves (a key, a signal) finds it moving."""
    monkeypatch.setenv("SPM_CONSOLE_CLOCK", "simulated:1")


def pytest_sessionstart(session: pytest.Session) -> None:
    """A parallel run's workers ask pytest-rerunfailures' status database (a TCP socket to the
    controller) about every test marked flaky: a write then a read, twice per test. Without
    TCP_NODELAY, Nagle's algorithm held the read behind the write until the controller's
    delayed acknowledgement, 40 ms later: about 40 ms in every test's teardown."""
    import socket

    sock = getattr(getattr(session.config, "failures_db", None), "sock", None)
    if isinstance(sock, socket.socket) and sock.family in (socket.AF_INET, socket.AF_INET6):
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)


def pytest_unconfigure(config: pytest.Config) -> None:
    stalls = config.pluginmanager.get_plugin("spm_host_stalls")
    if stalls is not None:
        stalls.stop()


@pytest.fixture(autouse=True)
def _no_collection_pause_during_a_test() -> Iterator[None]:
    """No cyclic collection of this process's heap while a test runs.

    Tests host emulated buses (``start_emulator``) and executors in a thread of the
    pytest process; late in a full run its heap is large and one collection can pause
    that thread for longer than the loop's reply timeout, which a run reports as a lost
    bus (a flake seen once in 870 tests). The product's own processes manage collection
    themselves (the motion process freezes it during motion); cyclic garbage of a test is
    collected after it, outside any run."""
    gc.disable()
    try:
        yield
    finally:
        gc.enable()


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def agile():  # type: ignore[no-untyped-def]
    from spm_console.config.load import load_profile

    return load_profile(ROOT / "profiles" / "agile_wrist.toml")


@pytest.fixture(scope="session")
def coaxial():  # type: ignore[no-untyped-def]
    from spm_console.config.load import load_profile

    return load_profile(ROOT / "profiles" / "coaxial_spm.toml")


@pytest.fixture(scope="session")
def agile_model(agile):  # type: ignore[no-untyped-def]
    from spm_console.config.models import model_of

    return model_of(agile)


@pytest.fixture
def sighup_default() -> Iterator[None]:
    """SIGHUP at its default for one test (and the processes it starts), even when the tests
    run under ``nohup``: the console leaves an ignored SIGHUP ignored (spm_console.system.signals)."""
    import signal

    old = signal.signal(signal.SIGHUP, signal.SIG_DFL)
    try:
        yield
    finally:
        signal.signal(signal.SIGHUP, old)
