"""The keys of a question's answers: each answer its own key, none shared, an answer of one
character its own key (a leg's number), a unique first letter next, else its place."""

from __future__ import annotations

import pytest

from spm_console.tui.widgets.answer import answer_keys


@pytest.mark.parametrize(("answers", "keys"), [
    (("1", "2", "3", "again"), ("1", "2", "3", "a")),
    (("up", "down", "again"), ("u", "d", "a")),
    (("clockwise", "counter-clockwise", "again"), ("1", "2", "a")),
    (("2", "two", "x"), ("2", "t", "x")),
    (("b", "2", "alpha", "another"), ("b", "2", "3", "4")),
    (("x", "3", "alpha", "another"), ("1", "2", "3", "4")),  # "3" would be taken twice
])
def test_each_answer_gets_a_key_of_its_own(answers: tuple[str, ...], keys: tuple[str, ...]) -> None:
    got = answer_keys(answers)
    assert got == keys
    assert len(set(got)) == len(answers)
