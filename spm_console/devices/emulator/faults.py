"""Faults the emulated servo bus injects on demand, and their command-line syntax.

``KIND[:ARG][@SECONDS]`` — for example ``unplug@1.0`` (no reply at all from 1 s on),
``stall:2@0.5`` (joint 2 stops moving at 0.5 s), ``drop:0.05`` (5 % of replies
lost), ``corrupt:0.02`` (2 % of replies with a broken CRC/checksum),
``delay:0.03@1.0`` (replies 30 ms late from 1 s on), ``hwerror:1@0.5`` (joint 1's
servo raises an overload alert and drops torque at 0.5 s). Times are seconds after
the emulator's clock starts: the first torque-on (the start of the first motion) or
``EmulatorHandle.start_clock``; a fault without ``@`` acts from power-on.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

from spm_console.errors import BadInputError
from spm_console.numbers import NotANumberError, parse_number

KINDS = ("unplug", "stall", "drop", "corrupt", "delay", "hwerror")

_USAGE = (
    "expected KIND[:ARG][@SECONDS] with KIND one of unplug, stall:JOINT, drop:RATE, "
    "corrupt:RATE, delay:SECONDS, hwerror:JOINT (e.g. 'unplug@1.0', 'stall:2@0.5', "
    "'drop:0.05', 'delay:0.03@1.0')"
)


@dataclass(frozen=True)
class FaultSpec:
    """One fault of the emulated bus."""

    kind: str
    """'unplug' | 'stall' | 'drop' | 'corrupt' | 'delay' | 'hwerror'."""
    at_s: float = 0.0
    """When it starts, seconds after the emulator's clock starts."""
    joint: int | None = None
    """1-based joint for 'stall' / 'hwerror'."""
    rate: float | None = None
    """Probability per reply for 'drop' / 'corrupt'."""
    delay_s: float | None = None
    """Extra reply delay for 'delay', seconds."""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise BadInputError(f"unknown fault kind {self.kind!r}: {_USAGE}")
        if not (math.isfinite(self.at_s) and self.at_s >= 0.0):
            raise BadInputError(f"fault {self.kind}: start time must be ≥ 0 s, got {self.at_s}")
        if self.kind in ("stall", "hwerror") and self.joint not in (1, 2, 3):
            raise BadInputError(f"fault {self.kind}: needs a joint 1, 2 or 3, got {self.joint}")
        if self.kind in ("drop", "corrupt") and not (
            self.rate is not None and math.isfinite(self.rate) and 0.0 < self.rate <= 1.0
        ):
            raise BadInputError(f"fault {self.kind}: needs a rate in (0, 1], got {self.rate}")
        if self.kind == "delay" and not (
            self.delay_s is not None and math.isfinite(self.delay_s) and 0.0 < self.delay_s <= 10.0
        ):
            raise BadInputError(f"fault delay: needs a delay in (0, 10] s, got {self.delay_s}")

    def __str__(self) -> str:
        arg = {"stall": self.joint, "hwerror": self.joint, "drop": self.rate,
               "corrupt": self.rate, "delay": self.delay_s}.get(self.kind)
        text = self.kind + (f":{arg}" if arg is not None else "")
        return text + (f"@{self.at_s:g}" if self.at_s else "")


class FaultNumberError(BadInputError):
    """A number of a fault's syntax that is not a finite plain ASCII decimal; ``text`` is it
    (a command line calls non-decimal text a usage error, as it does in a number option)."""

    def __init__(self, message: str, text: str = "") -> None:
        super().__init__(message)
        self.text = text


def _number(text: str, what: str, whole: str) -> float:
    """A number of the fault's syntax, by the rule of every number typed
    (:func:`~spm_console.numbers.parse_number`: plain ASCII decimals, finite)."""
    try:
        v = parse_number(text)
    except NotANumberError as exc:
        raise FaultNumberError(f"fault {whole!r}: {what}: {exc}; {_USAGE}", text) from None
    if v != 0.0 and abs(v) < sys.float_info.min:  # as every number typed (input_rules)
        raise BadInputError(f"fault {whole!r}: {what}: {text.strip()} is a subnormal number, "
                            "too small to mean anything (0 or a magnitude of at least 2.2e-308)")
    return v + 0.0  # −0 is 0


def parse_fault(text: str) -> FaultSpec:
    """Parse ``KIND[:ARG][@SECONDS]``; BadInputError names what is wrong."""
    whole = text
    text = text.strip()
    if not text:
        raise BadInputError(f"empty fault: {_USAGE}")
    at_s = 0.0
    if "@" in text:
        text, at = text.split("@", 1)
        at_s = _number(at, "start time", whole)
    kind, _, arg = text.partition(":")
    kind = kind.strip().lower()
    if kind not in KINDS:
        raise BadInputError(f"fault {whole!r}: unknown kind {kind!r}; {_USAGE}")
    if kind == "unplug":
        if arg:
            raise BadInputError(f"fault {whole!r}: unplug takes no argument; {_USAGE}")
        return FaultSpec("unplug", at_s)
    if not arg:
        raise BadInputError(f"fault {whole!r}: {kind} needs an argument; {_USAGE}")
    if kind in ("stall", "hwerror"):
        _number(arg, "joint", whole)  # not a decimal number: a usage error, as any number
        j = arg.strip()
        if j not in ("1", "2", "3"):
            raise BadInputError(f"fault {whole!r}: needs a joint 1, 2 or 3 (digits only), "
                                f"got {j!r}")
        return FaultSpec(kind, at_s, joint=int(j))
    if kind == "delay":
        return FaultSpec(kind, at_s, delay_s=_number(arg, "delay", whole))
    return FaultSpec(kind, at_s, rate=_number(arg, "rate", whole))
