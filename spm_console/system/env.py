"""Switches read from the environment."""

from __future__ import annotations

import os

#: The words that switch a feature off (any case, surrounding blanks ignored).
OFF_WORDS = ("0", "no", "off", "false")


def switched_off(name: str) -> bool:
    """Whether the environment variable ``name`` says off (``0``, ``no``, ``off``,
    ``false``); unset, empty or anything else leaves the feature on."""
    return os.environ.get(name, "").strip().lower() in OFF_WORDS
