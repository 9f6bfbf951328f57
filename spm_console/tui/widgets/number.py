"""Number fields that never alter what the operator typed.

A :class:`NumberField` is a plain text :class:`~textual.widgets.Input` (no ``type="number"``,
which silently drops characters): every keystroke stays in the field, and the text is
checked as it is typed against a :class:`NumberRule`. A field that does not parse or is
out of range carries the ``-invalid`` class, its container shows the reason, and the
screen refuses every action that would use it (:meth:`NumberField.number` raises
:class:`~spm_console.errors.BadInputError` with that reason).
"""

from __future__ import annotations

import math
import re
import sys
from dataclasses import dataclass

from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical
from textual.content import Content
from textual.widgets import Input, Label, Static

from spm_console.errors import BadInputError
from spm_console.input_rules import Bound
from spm_console.tui.widgets.field import TextField

#: Characters a number field accepts: its narrowest form shows this many in full (its CSS
#: width is this + cursor, padding, border; wider layouts show more), so an accepted value is
#: never partly hidden. The refusal says "accepted", not how many fit: that depends on the
#: layout.
FIELD_CHARS = 9

#: A decimal number as an operator writes it: optional sign (ASCII or U+2212 minus), ASCII
#: digits with at most one decimal point, optional exponent. Nothing else (no commas,
#: underscores, digits of other scripts, "inf" or "nan"), as on the command line.
_NUMBER = re.compile(r"[+\-\u2212]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+\-]?[0-9]+)?")


@dataclass(frozen=True)
class NumberRule:
    """What one field accepts, and the words its refusals use."""

    name: str
    """As the operator knows the field: "θ2", "goal roll", "steps N", "v_max"."""
    quantity: str = "a number"
    """What to type, for an empty or unparsable field: "a number of degrees"."""
    unit: str = ""
    """Appended to bounds in messages: "°", "°/s"."""
    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    """The value must be strictly above ``lo``."""
    integer: bool = False
    limits: str = ""
    """What [lo, hi] is called in messages: "the servo limits"."""
    hi_reason: str = ""
    """If set, a value above ``hi`` reads "{name}: {text} is above {hi_reason}"."""
    max_chars: int = FIELD_CHARS
    slack: float = 0.0
    """Values within this of ``lo`` or ``hi`` count as on it (see :class:`Bound`)."""

    @classmethod
    def of(cls, bound: Bound, name: str, quantity: str, unit: str, *, limits: str = "",
           hi_reason: str = "") -> NumberRule:
        """The field that accepts what ``bound`` (a shared input rule) accepts."""
        if bound.hi_open:
            raise ValueError("a number field's upper end is closed")
        return cls(name, quantity, unit, bound.lo, bound.hi, lo_open=bound.lo_open,
                   integer=bound.integer, limits=limits, hi_reason=hi_reason,
                   slack=bound.slack)

    @property
    def bound(self) -> Bound:
        """What the field accepts, as an input rule."""
        return Bound(self.lo, self.hi, lo_open=self.lo_open, integer=self.integer,
                     slack=self.slack)

    def _range(self) -> str:
        lo = "−∞" if math.isinf(self.lo) else f"{self.lo:g}"
        hi = "∞" if math.isinf(self.hi) else f"{self.hi:g}"
        words = f"{self.limits} " if self.limits else ""
        if self.lo_open:  # "0 must be above 0°" and "15 is outside (0, 10]°" agree
            return f"{words}({lo}, {hi}]{self.unit}"
        return f"{words}{lo}…{hi}{self.unit}"

    def parse(self, text: str) -> float:
        """The number in ``text`` (an ``int``-valued float when ``integer``), or
        BadInputError with the reason shown to the operator."""
        s = text.strip()
        if not s:
            raise BadInputError(f"{self.name}: empty, type {self.quantity}")
        if len(s) > self.max_chars:
            raise BadInputError(f"{self.name}: {len(s)} characters, at most {self.max_chars} "
                                "are accepted")
        if not _NUMBER.fullmatch(s):
            if "," in s and _NUMBER.fullmatch(s.replace(",", ".", 1)):
                raise BadInputError(f"{self.name}: {s!r} is not a number; decimals take a "
                                    f"point: {s.replace(',', '.', 1)}")
            raise BadInputError(f"{self.name}: {s!r} is not {self.quantity}")
        v = float(s.replace("\u2212", "-"))  # finite, or ±inf when the exponent overflows
        bound = self.bound
        if v > self.hi + self.slack and self.hi_reason:
            raise BadInputError(f"{self.name}: {s} is above {self.hi_reason}")
        if self.integer and math.isfinite(v) and not v.is_integer():
            raise BadInputError(f"{self.name}: {s} must be a whole number")
        if not bound.contains(v):
            if self.lo_open and v <= self.lo:
                raise BadInputError(f"{self.name}: {s} must be above {self.lo:g}{self.unit}")
            raise BadInputError(f"{self.name}: {s} is outside {self._range()}")
        if not math.isfinite(v):
            raise BadInputError(f"{self.name}: {s} is too large")
        if v != 0.0 and abs(v) < sys.float_info.min:  # as the command line's and a profile's
            raise BadInputError(f"{self.name}: {s} is too small to be a measurement "
                                "(a subnormal number)")
        return float(int(v)) if self.integer else v

    def reason(self, text: str) -> str:
        """Why ``text`` is refused ("" when it is accepted)."""
        try:
            self.parse(text)
        except BadInputError as exc:
            return exc.message
        return ""


class NumberField(TextField):
    """A plain text field checked against a :class:`NumberRule` as it is typed.

    ``-invalid`` marks a refused text (or, via :attr:`extra_reason`, a value its container
    refused as a whole, e.g. an orientation IK cannot reach). Disabled fields are not marked.
    """

    DEFAULT_CLASSES = "number"
    DEFAULT_CSS = f"""
    NumberField {{
        width: {FIELD_CHARS + 5};  /* the text, the cursor after it, padding 0 1, border */
        padding: 0 1;
    }}
    """

    def __init__(self, rule: NumberRule, value: str = "", *, placeholder: str = "",
                 id: str | None = None, classes: str | None = None) -> None:
        # validate_on=(): Input's own validation would reset the class this widget sets
        super().__init__(value, placeholder=placeholder or rule.name, validate_on=(), id=id,
                         classes=classes, tooltip=f"{rule.name}: {rule.quantity}")
        self.rule = rule
        self.extra_reason = ""

    @property
    def reason(self) -> str:
        """Why the field is refused ("" when accepted)."""
        return self.rule.reason(self.value) or self.extra_reason

    def number(self) -> float:
        """The value, or BadInputError with the reason."""
        v = self.rule.parse(self.value)
        if self.extra_reason:
            raise BadInputError(self.extra_reason)
        return v

    def set_rule(self, rule: NumberRule) -> None:
        self.rule = rule
        self.tooltip = f"{rule.name}: {rule.quantity}"
        self.mark()

    def mark(self) -> None:
        self.set_class(bool(self.reason) and not self.is_disabled, "-invalid")

    def on_input_changed(self, event: Input.Changed) -> None:
        # runs before the event bubbles to the container, which shows the reason
        if event.input is self:
            self.mark()


def show_reasons(line: Static, reasons: list[str]) -> None:
    """Put the refusal reasons in ``line`` (plain text), hidden when there are none."""
    line.update(Content("\n".join(reasons)))
    line.display = bool(reasons)


class NumberRow(Vertical):
    """A label and one :class:`NumberField` (``id`` is the field's), the reason below."""

    DEFAULT_CLASSES = "number-row"

    def __init__(self, label: str, rule: NumberRule, value: str, *, id: str) -> None:
        super().__init__(id=f"{id}-row")
        self._label = label
        self._field = NumberField(rule, value, id=id)

    def compose(self) -> ComposeResult:
        with Horizontal(classes="param"):
            yield Label(self._label, classes="param-label", markup=False)
            yield self._field
        yield Static(classes="entry-reason", markup=False)

    @property
    def field(self) -> NumberField:
        return self._field

    def on_mount(self) -> None:
        self.revalidate()

    def on_input_changed(self, event: Input.Changed) -> None:
        self.revalidate()

    def set_enabled(self, enabled: bool) -> None:
        """Enable the row, or disable it (not used: never marked, never refused)."""
        self.disabled = not enabled
        self.revalidate()

    def revalidate(self) -> None:
        self._field.mark()
        reason = "" if self.is_disabled else self._field.reason
        show_reasons(self.query_one(".entry-reason", Static), [reason] if reason else [])

    def number(self) -> float:
        return self._field.number()
