"""A small sweep spec on a coarse grid (10°): designs build in a tenth of a second."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from tests.support.paths import ROOT

AGILE = ROOT / "profiles" / "agile_wrist.toml"


def spec_text(parameters: str, sweep: str = "", pairs: str = "") -> str:
    step = "" if "step_deg" in sweep else "step_deg = 10.0\n"
    return f'[sweep]\nbase_profile = "{AGILE}"\n{step}{sweep}\n{parameters}\n{pairs}\n'



@pytest.fixture
def write_spec(tmp_path: Path) -> Callable[..., Path]:
    def write(parameters: str, sweep: str = "", pairs: str = "", name: str = "spec.toml") -> Path:
        p = tmp_path / name
        p.write_text(spec_text(parameters, sweep, pairs))
        return p

    return write


GRID = """
[parameters.alpha1_deg]
min = 80.0
max = 100.0
count = 3

[parameters.delta_mm]
min = 12.0
max = 60.0
count = 2
"""
