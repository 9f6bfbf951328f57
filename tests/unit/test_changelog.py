"""The CHANGELOG: one line per user-visible change under a version heading, each at most 160
characters (what was tried and measured lives in docs/decisions/)."""

from __future__ import annotations

from tests.support.paths import ROOT

MAX_LINE = 160


def test_every_change_is_one_short_line_under_a_version() -> None:
    lines = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8").splitlines()
    version = ""
    bullets = 0
    for n, line in enumerate(lines, 1):
        if line.startswith("## ["):
            version = line
        if line.startswith("- "):
            bullets += 1
            assert version, f"CHANGELOG.md:{n}: a change before any version heading"
            assert len(line) <= MAX_LINE, f"CHANGELOG.md:{n}: {len(line)} characters"
        elif line.startswith("  ") and lines[n - 2].startswith(("- ", "  ")):
            raise AssertionError(f"CHANGELOG.md:{n}: a change continued on a second line")
    assert bullets > 0
