"""The plan step's sentence about a minimum-time plan's proof, in each of its cases."""

from __future__ import annotations

from types import SimpleNamespace
from typing import cast

from spm_console.core.plan import Plan
from spm_console.core.plan_report import Certificate, InfeasibilityRecord
from spm_console.tui.screens.plan_words import proof_text


def _plan(cert: Certificate | None, scope: str = "", n: int = 64) -> Plan:
    rec = InfeasibilityRecord(N=n, certificate=cert, scope=scope)
    return cast(Plan, SimpleNamespace(certificate=rec, Ts=0.02))


def _cert(valid: bool) -> Certificate:
    return Certificate(residual_l1=1e-12, cone_violation=0.0, excluded_radius=float("inf"),
                       rows=100, valid=valid)


def test_a_checked_proof_says_what_cannot_be_done_one_step_sooner() -> None:
    text = proof_text(_plan(_cert(True)))
    assert text == ("fastest possible: no reference reaches the goal in N−1 = 64 steps (1.28 s) "
                    "within these limits (v_max, the servo limits, the workspace region); "
                    "proven by a checked infeasibility certificate")


def test_a_route_proof_says_it_holds_for_that_route_only() -> None:
    text = proof_text(_plan(_cert(True), scope="for this sequence of 3 regions"))
    assert "along this route of regions: another route might be faster" in text


def test_a_proof_that_did_not_check_out_says_so_first() -> None:
    text = proof_text(_plan(_cert(False)))
    assert text.startswith("NOT proven fastest:") and "a shorter plan may exist" in text


def test_the_smallest_horizon_needs_no_proof() -> None:
    assert proof_text(_plan(None, n=1)) == ("fastest possible: N = 2 steps is the fewest a "
                                            "plan can have")
