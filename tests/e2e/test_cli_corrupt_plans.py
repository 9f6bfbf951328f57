"""Every command that reads a plan file refuses a corrupt one with exit 9, before the bus opens."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import pytest

from spm_console.cli.main import main
from spm_console.errors import ExitCode
from tests.unit.store.test_plan_file_hostile import _write, valid  # noqa: F401


def test_cli_exit_code_9_for_corrupt_plans(valid: dict[str, Any], tmp_path: Path,  # noqa: F811
                                           capsys: pytest.CaptureFixture[str]) -> None:
    bad = copy.deepcopy(valid)
    bad["extra"] = [1, 2]
    path = _write(tmp_path, bad)
    for argv in (["plan", "show", str(path)], ["plan", "show", str(path), "--json"],
                 ["execute", "--sim", "--plan", str(path), "--logs", str(tmp_path / "logs")]):
        assert main(argv) == ExitCode.PLAN_MISMATCH
        out, err = capsys.readouterr()
        assert "'extra' must be an object" in err and "Traceback" not in err
        if "--json" in argv:  # the failure as one JSON object
            assert json.loads(out)["exit_code"] == ExitCode.PLAN_MISMATCH
        else:
            assert out == ""
