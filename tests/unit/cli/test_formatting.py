"""Text shown to people: a value that rounds to zero never reads −0."""

from __future__ import annotations

from spm_console.formatting import fmt_deg, fmt_num, fmt_vec


def test_values_rounding_to_zero_read_zero_with_or_without_a_sign() -> None:
    assert fmt_deg([0.0, -0.0, -0.001]) == "[0.00, 0.00, 0.00]°"
    assert fmt_vec([-0.0001, 0.0, 1.0], 3, signed=True) == "[+0.000, +0.000, +1.000]"
    assert fmt_num(-0.004, 2) == "0.00" and fmt_num(-0.006, 2) == "-0.01"
    assert fmt_vec([-2.5, 2.5], 1) == "[-2.5, 2.5]"
