"""Unit tests need no process and no terminal: this folder's tests fail if they start one.

A fresh interpreter that only imports and prints (``python -c``, the import-hygiene probes)
is allowed; a motion process, an emulator, a front end, a fork or a pseudo-terminal is not
(such a test belongs in tests/runtime or tests/e2e). A workspace built here is built in this
process: the forked row helper (tests/runtime/test_forked.py) is off, as in any process that
runs threads; the unit tests run on every core instead (``make test-unit``).
"""

from __future__ import annotations

import os
import pty
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import pytest

from spm_console.system import forked


class StartsAProcessError(AssertionError):
    """A unit test started a process or a terminal."""


def _refuse(what: str) -> Any:
    def refuse(*_a: object, **_k: object) -> Any:
        raise StartsAProcessError(f"a unit test may not start {what}: move it to tests/runtime or "
                             "tests/e2e")
    return refuse


@pytest.fixture(autouse=True)
def _no_process_no_terminal(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    real_init = subprocess.Popen.__init__

    def popen(self: subprocess.Popen[Any], args: Any, *a: Any, **k: Any) -> None:
        argv = list(args) if isinstance(args, (list, tuple)) else [args]
        if len(argv) < 2 or argv[0] != sys.executable or argv[1] != "-c":
            _refuse(f"a process ({' '.join(map(str, argv))[:80]})")()
        real_init(self, args, *a, **k)

    monkeypatch.setattr(forked, "fork_useful", lambda: False)
    # a moving command starts the motion process's warm start as it begins; the tests here
    # call such commands only for what they refuse before any process would serve them
    monkeypatch.setenv("SPM_CONSOLE_WARM_START", "0")
    monkeypatch.setattr(subprocess.Popen, "__init__", popen)
    monkeypatch.setattr(os, "fork", _refuse("a fork"))
    monkeypatch.setattr(os, "openpty", _refuse("a pseudo-terminal"))
    monkeypatch.setattr(pty, "openpty", _refuse("a pseudo-terminal"))
    yield
