"""Shared fixtures. Tests run from the project root (profiles/ is relative to it)."""

from __future__ import annotations

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


@pytest.fixture(scope="session")
def root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def agile():  # type: ignore[no-untyped-def]
    from spm_console.profile import load_profile

    return load_profile(ROOT / "profiles" / "agile_wrist.toml")


@pytest.fixture(scope="session")
def coaxial():  # type: ignore[no-untyped-def]
    from spm_console.profile import load_profile

    return load_profile(ROOT / "profiles" / "coaxial_spm.toml")


@pytest.fixture(scope="session")
def agile_model(agile):  # type: ignore[no-untyped-def]
    from spm_console.models import model_of

    return model_of(agile)


@pytest.fixture
def sighup_default() -> Iterator[None]:
    """SIGHUP at its default for one test (and the processes it starts), even when the tests
    run under ``nohup``: the console leaves an ignored SIGHUP ignored (run.signals)."""
    import signal

    old = signal.signal(signal.SIGHUP, signal.SIG_DFL)
    try:
        yield
    finally:
        signal.signal(signal.SIGHUP, old)
