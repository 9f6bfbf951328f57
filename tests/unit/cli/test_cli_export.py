"""``spm-console export urdf|mjcf``: files written, bad output paths refused before any work."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import pytest

from spm_console.cli.main import main
from spm_console.errors import ExitCode


def test_export_writes_both_formats(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    urdf, mjcf = tmp_path / "wrist.urdf", tmp_path / "wrist.xml"
    assert main(["export", "urdf", "--out", str(urdf), "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["ok"] and rec["format"] == "urdf" and rec["out"] == str(urdf)
    assert rec["bytes"] == len(urdf.read_bytes())
    assert "<robot name=\"agile_wrist\">" in urdf.read_text()
    assert main(["export", "mjcf", "--out", str(mjcf)]) == 0
    assert "MJCF of 'agile_wrist' written to" in capsys.readouterr().out
    mujoco.MjModel.from_xml_path(str(mjcf))  # loads as it is
    assert "[plant] link_mass_kg = 0.12: Mass of each proximal and distal link" in mjcf.read_text()


@pytest.mark.parametrize("out", ["wrist.txt", "missing/wrist.urdf", "."])
def test_export_refuses_bad_output_paths(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                         out: str) -> None:
    target = tmp_path / out if out != "." else tmp_path
    code = main(["export", "urdf", "--out", str(target), "--json"])
    assert code == ExitCode.BAD_INPUT
    assert json.loads(capsys.readouterr().out)["ok"] is False
    assert not (tmp_path / "wrist.txt").exists()
