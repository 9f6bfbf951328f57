"""Committed snapshots carry no digits below their meaning (they differ between machines).

A residual of 5.5e-16 on one CPU is 7.4e-16 on another; a timing or a port changes every
run. Such values must be shown as a bound or kept out of snapshots (docs/development.md).
"""

from __future__ import annotations

import html
import re
from pathlib import Path

import pytest

from spm_console.formatting import fmt_residual
from tests.support.paths import TESTS

SNAPSHOTS = sorted(TESTS.rglob("__snapshots__/**/*.svg"))

#: Text that only a particular machine or run produces.
MACHINE_DIGITS = {
    # a bound ("< 1e-12") is fine; a value ("7.4e-16") is not
    "a float with an exponent of -10 or below": re.compile(r"(?<![\d.])(?<!< )(?<!≤ )\d\.?\d*e-(1\d|[2-9]\d)"),
    "a time in ms or µs": re.compile(r"\d+(\.\d+)?\s?(ms|µs)\b"),
    "a loopback port": re.compile(r"127\.0\.0\.1:\d+"),
    "a date": re.compile(r"\b20\d\d-\d\d-\d\d\b"),
}


def _text(svg: Path) -> str:
    return html.unescape(re.sub(r"<[^>]+>", "", svg.read_text())).replace("\xa0", " ")


def test_there_are_snapshots() -> None:
    assert len(SNAPSHOTS) >= 3


@pytest.mark.parametrize("svg", SNAPSHOTS, ids=lambda p: p.stem)
def test_snapshot_has_no_machine_dependent_digits(svg: Path) -> None:
    text = _text(svg)
    found = {what: m.group(0) for what, rx in MACHINE_DIGITS.items() if (m := rx.search(text))}
    assert not found, f"{svg.name} shows {found}"


def test_residuals_are_shown_as_a_bound() -> None:
    assert fmt_residual(5.5e-16) == fmt_residual(7.4e-16) == "< 1e-12"
    assert fmt_residual(3.2e-9) == "3.2e-09"
