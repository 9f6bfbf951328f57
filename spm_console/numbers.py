"""Strict numbers from text and JSON: the one rule every input path uses.

Python's ``float()`` accepts more than an operator means: ``1_25`` (125), non-ASCII digits
(``١٢٥``), ``nan``, ``inf``, surrounding whitespace; JSON decoders turn a 400-digit integer
into an ``int`` that overflows when made a float, and ``true`` into a number in lax
validation. Here a number is plain ASCII decimal notation (optional sign, digits, one
decimal point, an optional exponent) whose value is finite, and an integer is plain ASCII
digits; in JSON, an ``int`` or ``float`` that is not a boolean and fits a finite float.
Command-line options (:func:`spm_console.cli.common.number`), fault specs, target files and
UDP messages read their numbers here.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterator

from spm_console.errors import BadInputError

_DECIMAL = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_INTEGER = re.compile(r"[+-]?[0-9]+")
#: Longest numeral read (digits of a double are 17; room for zeros and an exponent).
MAX_NUMERAL_CHARS = 64


class NotANumberError(ValueError):
    """Text or a JSON value that is not a finite number; the message says why."""


def looks_numeric(text: str) -> bool:
    """Whether ``text`` is written as a decimal numeral (finite or not): a cell that does is
    a value, never a header."""
    t = text.strip()
    return bool(_DECIMAL.fullmatch(t)) or t.lower().lstrip("+-") in ("nan", "inf", "infinity")


def parse_number(text: str) -> float:
    """The finite value of a plain ASCII decimal numeral (``12``, ``-0.5``, ``1e-3``);
    :class:`NotANumberError` for anything else."""
    t = text.strip()
    if len(t) > MAX_NUMERAL_CHARS:
        raise NotANumberError(f"a number of more than {MAX_NUMERAL_CHARS} characters")
    if not _DECIMAL.fullmatch(t):
        if looks_numeric(t):
            raise NotANumberError(f"{t[:20]!r} is not a finite number")
        raise NotANumberError(f"{t[:20]!r} is not a decimal number")
    v = float(t)
    if not math.isfinite(v):
        raise NotANumberError(f"{t[:20]} is beyond the range of a number")
    return v


def parse_integer(text: str) -> int:
    """The value of a plain ASCII decimal integer (``12``, ``-3``), at most
    :data:`MAX_NUMERAL_CHARS` characters; :class:`NotANumberError` for anything else (``1_0``,
    ``١٠``, ``1e3``, ``2.0``)."""
    t = text.strip()
    if len(t) > MAX_NUMERAL_CHARS:
        raise NotANumberError(f"an integer of more than {MAX_NUMERAL_CHARS} characters")
    if not _INTEGER.fullmatch(t):
        raise NotANumberError(f"{t[:20]!r} is not a whole number in decimal digits")
    return int(t)


def json_number(value: object) -> float:
    """A JSON value that is a finite number (``int`` or ``float``, never a boolean, an
    integer that fits a float); :class:`NotANumberError` otherwise."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise NotANumberError(f"{type(value).__name__} is not a number")
    if isinstance(value, int) and abs(value) > 2**1023:
        raise NotANumberError("an integer beyond the range of a number")
    v = float(value)
    if not math.isfinite(v):
        raise NotANumberError("not a finite number")
    return v


def _refuse_constant(name: str) -> float:
    raise NotANumberError(f"{name} is not a finite number")


def _bounded_int(text: str) -> int | float:
    """JSON integers: more digits than any finite float has are refused while decoding
    (Python's own limit would raise a bare ValueError at 4,300 digits)."""
    if len(text.lstrip("-")) > 309:
        raise NotANumberError("an integer beyond the range of a number")
    return int(text)


def json_loads(text: str | bytes) -> object:
    """:func:`json.loads` refusing ``NaN``/``Infinity`` and integers beyond a float's range
    while decoding (:class:`NotANumberError`); malformed JSON raises ``ValueError``."""
    return json.loads(text, parse_constant=_refuse_constant, parse_int=_bounded_int)


def _is_name(cell: str) -> bool:
    """A header cell: a name that begins with a letter (``t``, ``theta1``, ``θ1``) and is not
    a numeral (``nan``, ``inf``); an empty cell, a digit of any script or a quote is not."""
    return bool(cell) and cell[0].isalpha() and not looks_numeric(cell)


_WORDS = {1: "one", 2: "two", 3: "three", 4: "four", 5: "five", 6: "six", 7: "seven"}


def numeric_rows(text: str, where: str, width: int, expect: str) -> Iterator[tuple[int, list[float]]]:
    """The rows of a CSV text of numbers: ``(line number, values)``.

    ``#`` starts a comment; blank lines are skipped; the first other line is a header, and
    skipped, only when every cell is a name that begins with a letter (so a typo in the first
    row, ``1_0``, digits of another script or quoted numbers are an error at line 1, never a
    header). Every row has ``width`` plain decimal numbers
    (:func:`parse_number`); otherwise :class:`~spm_console.errors.BadInputError` names
    ``where``, the line and ``expect`` (e.g. "t and three angles").
    """
    count = _WORDS.get(width, str(width))
    first = True
    for n, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        cells = [c.strip() for c in line.split(",")]
        if first and all(_is_name(c) for c in cells):
            first = False
            continue
        first = False
        if len(cells) != width:
            raise BadInputError(f"{where}:{n}: {count} numbers expected ({expect}), got "
                                f"{len(cells)} values")
        try:
            yield n, [parse_number(c) for c in cells]
        except NotANumberError as exc:
            raise BadInputError(f"{where}:{n}: {count} numbers expected ({expect}): "
                                f"{exc}") from None
