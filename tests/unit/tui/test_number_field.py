"""The console's number fields read numbers as the command line does: ASCII digits only."""

from __future__ import annotations

import pytest

from spm_console.errors import BadInputError
from spm_console.tui.widgets.number import NumberRule

RULE = NumberRule("θ1", "a number of degrees", "°", -360.0, 360.0)


@pytest.mark.parametrize("text", ["١٠", "۱۰", "１０", "1_0"])
def test_digits_of_other_scripts_are_not_a_number(text: str) -> None:
    """``float()`` reads Arabic-Indic (and fullwidth) digits; the field's pattern took them
    too (its ``\\d``), where a CSV cell or a command-line option refuses them."""
    with pytest.raises(BadInputError, match="is not a number of degrees"):
        RULE.parse(text)


def test_plain_decimals_and_the_minus_sign_are_numbers() -> None:
    assert RULE.parse("10") == 10.0 and RULE.parse("\u22122.5") == -2.5


def test_a_subnormal_number_is_refused_as_the_command_line_refuses_it() -> None:
    """The console's payload mass field took 1e-320 (a commissioning then failed in the
    profile's validation after all its motion)."""
    from spm_console.tui.screens.commission import PAYLOAD_RULE

    assert "subnormal" in PAYLOAD_RULE.reason("1e-320")
    assert PAYLOAD_RULE.reason("0.3") == ""
    assert "subnormal" in NumberRule("x").reason("-4e-310")
