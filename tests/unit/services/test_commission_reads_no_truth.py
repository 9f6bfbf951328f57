"""Commissioning finds the wrist from the bus and the IMU alone: none of its code reads the
emulator's as-built description or truth log (only the emulator and its tests do)."""

from __future__ import annotations

import ast

from tests.support.paths import ROOT

COMMISSIONING = [
    *sorted((ROOT / "spm_console" / "services" / "commissioning").glob("*.py")),
    ROOT / "spm_console" / "cli" / "commission.py",
    *sorted((ROOT / "spm_console" / "core" / "commissioning").glob("*.py")),
]
FORBIDDEN = ("as_built", "truth_log", "twin", "emulator")


def test_no_commissioning_module_imports_the_truth() -> None:
    for path in COMMISSIONING:
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            for name in names:
                assert not any(word in name.split(".") or f".{word}" in name
                               for word in FORBIDDEN), f"{path.name} imports {name}"


def test_no_commissioning_module_names_the_truth_files() -> None:
    for path in COMMISSIONING:
        text = path.read_text()
        for word in ("--as-built", "--truth-log", "truth.csv", "[as_built]"):
            assert word not in text, f"{path.name} mentions {word}"
