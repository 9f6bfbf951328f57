"""The reproduction report's figures: its kinematics section against the paper's printed
numbers (eqs. 32, 34, Tables I and II), its verdict rules, and a plan figure that is an
image of the size asked."""

from __future__ import annotations

from pathlib import Path

import matplotlib.image
import pytest

from spm_console.config.models import servo_model_of
from spm_console.config.schema import Profile
from spm_console.core.planning.mvn import solve_mvn
from spm_console.core.polytope.region import Region
from spm_console.report.plot_plan import plot_plan
from spm_console.report.repro_kin import fk_section
from spm_console.report.repro_types import Check
from tests.support.exec_helpers import PAPER_GOAL, PAPER_START


def test_the_kinematics_section_reproduces_the_papers_printed_numbers(agile: Profile,
                                                                       coaxial: Profile) -> None:
    sec = fk_section(agile, coaxial)
    assert len(sec.checks) >= 6 and sec.anchor == "fk"
    for c in sec.checks:
        assert c.diff is not None and c.tol is not None, c.quantity
        assert c.verdict == "reproduced", (c.quantity, c.paper, c.ours, c.diff, c.tol)


@pytest.mark.parametrize(("diff", "tol", "explained", "verdict"), [
    (1e-5, 1e-4, "", "reproduced"),
    (1e-4, 1e-4, "", "reproduced"),  # the printed precision itself still matches
    (1e-3, 1e-4, "", "NOT reproduced"),
    (1e-3, 1e-4, "see §3", "differs (explained)"),
    (None, None, "", "reported"),
    (None, None, "why", "differs (explained)"),
])
def test_a_checks_verdict(diff: float | None, tol: float | None, explained: str,
                          verdict: str) -> None:
    assert Check("q", "1", "2", diff, tol, explained).verdict == verdict


def test_a_plan_figure_is_an_image_of_the_size_asked(agile: Profile, tmp_path: Path) -> None:
    res = solve_mvn(servo_model_of(agile), PAPER_START, PAPER_GOAL, 60, Region.box(65.0, 155.0))
    out = plot_plan(res.to_plan("mvn", ""), tmp_path / "plan.png")
    img = matplotlib.image.imread(out)
    assert img.shape[:2] == (8 * 110, 11 * 110)  # figsize (11, 8) in at 110 dpi
    assert float(img[..., :3].std()) > 0.05  # something is drawn on it
