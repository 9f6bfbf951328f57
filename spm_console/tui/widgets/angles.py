"""Three angle fields in a row (θ1..θ3 or roll/pitch/yaw), in degrees."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from textual.app import ComposeResult
from textual.containers import Horizontal
from textual.widgets import Input, Label

from spm_console.errors import BadInputError


class AnglesInput(Horizontal):
    """A label and three number fields; :meth:`values` validates them."""

    DEFAULT_CLASSES = "angles"

    def __init__(self, label: str, names: Sequence[str], values: Sequence[float] | None = None,
                 *, id: str | None = None) -> None:
        super().__init__(id=id)
        self._label = label
        self._names = list(names)
        self._initial = list(values) if values is not None else None

    def compose(self) -> ComposeResult:
        yield Label(self._label, classes="angles-label", markup=False)
        for i, name in enumerate(self._names):
            value = "" if self._initial is None else f"{self._initial[i]:g}"
            yield Input(value=value, placeholder=name, type="number", classes="angle",
                        id=f"{self.id}-{i}" if self.id else None, tooltip=f"{name}, degrees")

    @property
    def fields(self) -> list[Input]:
        return list(self.query(Input))

    def values(self) -> list[float]:
        """The three numbers (deg); BadInputError naming the empty or bad field."""
        out = []
        for name, field in zip(self._names, self.fields, strict=True):
            text = field.value.strip()
            try:
                v = float(text)
            except ValueError:
                raise BadInputError(f"{self._label}: {name} must be a number of degrees, "
                                    f"got {text!r}") from None
            if not math.isfinite(v):
                raise BadInputError(f"{self._label}: {name} must be finite")
            out.append(v)
        return out

    def set_values(self, values: Sequence[float] | Any, digits: int = 2) -> None:
        for field, v in zip(self.fields, values, strict=True):
            field.value = f"{float(v):.{digits}f}".rstrip("0").rstrip(".")
