"""`reproduce` on reduced settings: the report's tables and figures exist and hold numbers."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from spm_console.cli.main import main


@pytest.mark.slow  # a whole real-time run (the slow set runs in CI as its own stage)
def test_reproduce_quick(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "repro"
    code = main(["reproduce", "--out", str(out), "--quick", "--json"])
    summary = json.loads(capsys.readouterr().out)
    assert code == 0, summary
    assert summary["not_reproduced"] == 0
    assert summary["reproduced"] >= 8
    report = (out / "report.md").read_text()
    for anchor in ("fk", "eq35", "workspace", "mvn", "mintime"):
        assert f'<a id="{anchor}"></a>' in report
    # every table row has a verdict and the FK rows carry numbers
    rows = [r for r in report.splitlines() if r.startswith("| ") and not r.startswith("| quantity")]
    assert len(rows) >= 20
    assert re.search(r"\| eq\. \(34\): v1\.\.v3 \|.*\| [0-9.e+-]+ \| reproduced \|", report)
    assert "eigenvalues 1.912" in report
    # the minimum-time pair is planned on the profile's own 2° grid (refined near the
    # boundary), verified by the runtime's check, and executed
    mintime = report.split('<a id="mintime"></a>')[1]
    assert "(2° grid, refined to h = 0.5° near the boundary)" in mintime
    assert re.search(r"\| N\* \(minimum feasible horizon\) \|[^|]*\| \d+ \(", mintime)
    assert "| the runtime's plan verification (before torque-on) | not printed | passed:" in mintime
    assert "execution on the emulated MX-106 bus | completed on the prototype | completed" in mintime
    figures = re.findall(r"!\[[^\]]*\]\(([^)]+\.png)\)", report)
    assert len(figures) >= 2
    for f in figures:
        p = out / f
        assert p.exists() and p.stat().st_size > 10_000, f
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
