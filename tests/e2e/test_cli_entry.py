"""The command-line entry points as a user starts them: exit codes, no traceback, light imports."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from spm_console.errors import ExitCode
from tests.support.paths import TESTS

DATA = TESTS / "data" / "profiles"

def test_console_script_exits_3_without_traceback() -> None:
    fixture = "sign_seed_wrong.toml"  # the slowest path: the home check solves the kinematics
    out = subprocess.run([sys.executable, "-m", "spm_console", "fk", "--theta", "100", "100", "100",
                          "--profile", str(DATA / fixture)], capture_output=True, text=True, timeout=120)
    assert out.returncode == ExitCode.PROFILE_ERROR
    assert out.stderr.startswith(f"error: {DATA / fixture}: key '") and "Traceback" not in out.stderr

def test_python_m_entry_point() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "spm_console", "fk", "--theta", "135", "135", "135", "--json"],
        capture_output=True, text=True, check=True,
    )
    assert json.loads(out.stdout)["zeta"] == pytest.approx(1.0)

def test_tui_command_does_not_import_solvers() -> None:
    code = (
        "import sys\nfrom spm_console.cli.main import build_parser\nbuild_parser('tui')\n"
        "print(','.join(m for m in ('cvxpy', 'matplotlib', 'control') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
