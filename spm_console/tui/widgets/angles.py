"""Three angle fields in a row (θ1..θ3 or roll/pitch/yaw), in degrees, checked as typed."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from textual.app import ComposeResult
from textual.containers import Horizontal, Vertical
from textual.content import Content
from textual.widgets import Input, Label, Static

from spm_console.errors import BadInputError
from spm_console.tui.widgets.number import NumberField, NumberRule, show_reasons
from spm_console.tui.widgets.rules import TripleCheck


def field_name(rule: NumberRule) -> str:
    """What the label above a field says: its quantity without the "start "/"goal " the
    messages carry, and its unit ("roll (°)", "θ2 (°)")."""
    name = rule.name.split()[-1] if rule.name.split() else rule.name
    return f"{name} ({rule.unit})" if rule.unit else name


class AnglesInput(Vertical):
    """A label and three :class:`NumberField`, each named above it (with its unit), the
    reasons of any refusal below them.

    Each field is checked against its rule as it is typed; when all three are accepted,
    ``check`` (if any) judges them together (e.g. IK reach) and marks all three if it
    refuses. :meth:`values` returns the numbers or raises BadInputError with the reason.
    """

    DEFAULT_CLASSES = "angles"

    def __init__(self, label: str, names: Sequence[str], values: Sequence[float] | None = None,
                 *, rules: Sequence[NumberRule] | None = None, check: TripleCheck | None = None,
                 id: str | None = None) -> None:
        super().__init__(id=id)
        self._label = label
        self._rules = (list(rules) if rules is not None else
                       [NumberRule(name, "a number of degrees", "°") for name in names])
        self._check = check
        self._initial = list(values) if values is not None else None

    def compose(self) -> ComposeResult:
        with Horizontal(classes="angles-row"):
            if self._label:
                yield Label(self._label, classes="angles-label", markup=False)
            for i, rule in enumerate(self._rules):
                value = "" if self._initial is None else f"{self._initial[i]:g}"
                with Vertical(classes="angle-cell"):
                    # the placeholder names a field only while it is empty
                    yield Label(field_name(rule), classes="angle-name", markup=False)
                    yield NumberField(rule, value, classes="angle",
                                      id=f"{self.id}-{i}" if self.id else None)
        yield Static(classes="entry-reason", markup=False)

    @property
    def fields(self) -> list[NumberField]:
        return list(self.query(NumberField))

    def on_mount(self) -> None:
        self.revalidate()

    def on_input_changed(self, event: Input.Changed) -> None:
        self.revalidate()

    def set_rules(self, rules: Sequence[NumberRule], check: TripleCheck | None = None) -> None:
        """Judge the fields by other rules (the text stays as typed)."""
        self._rules = list(rules)
        self._check = check
        names = list(self.query(".angle-name").results(Label))
        for field, name, rule in zip(self.fields, names, self._rules, strict=True):
            field.rule = rule
            field.placeholder = rule.name
            field.tooltip = f"{rule.name}: {rule.quantity}"
            name.update(Content(field_name(rule)))
        self.revalidate()

    def set_enabled(self, enabled: bool) -> None:
        """Enable the fields, or disable them (not used: never marked, never refused)."""
        self.disabled = not enabled
        self.revalidate()

    def reasons(self) -> list[str]:
        """Why the fields are refused, first field first ([] when all are accepted)."""
        out = [r for r in (f.rule.reason(f.value) for f in self.fields) if r]
        if not out and self._check is not None:
            whole = self._check([f.rule.parse(f.value) for f in self.fields])
            if whole:
                out.append(whole)
        return out

    def revalidate(self) -> None:
        """Mark refused fields and show why (nothing when disabled)."""
        fields = self.fields
        if len(fields) != len(self._rules):
            return  # not composed yet
        reasons = [] if self.is_disabled else self.reasons()
        whole = bool(reasons) and not any(f.rule.reason(f.value) for f in fields)
        for f in fields:
            f.extra_reason = reasons[0] if whole else ""
            f.mark()
        show_reasons(self.query_one(".entry-reason", Static), reasons)

    def values(self) -> list[float]:
        """The three numbers (deg); BadInputError with the reason of the first refusal."""
        reasons = self.reasons()
        if reasons:
            raise BadInputError(reasons[0])
        return [f.rule.parse(f.value) for f in self.fields]

    def set_values(self, values: Sequence[float] | Any, digits: int = 2) -> None:
        for field, v in zip(self.fields, values, strict=True):
            field.value = f"{float(v):.{digits}f}".rstrip("0").rstrip(".")
