"""Building blocks of the reproduction report: checks (paper vs ours) and sections."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Check:
    """One printed number (or group) of the paper against ours."""

    quantity: str
    paper: str
    ours: str
    diff: float | None
    """Max absolute difference (None when not comparable)."""
    tol: float | None
    """The paper's printed precision (None when not comparable)."""
    explained: str = ""
    """Why ours differs when it cannot match (links to the report's explanation)."""

    @property
    def verdict(self) -> str:
        if self.diff is not None and self.tol is not None and self.diff <= self.tol:
            return "reproduced"
        if self.explained:
            return "differs (explained)"
        if self.diff is None:
            return "reported"
        return "NOT reproduced"


@dataclass
class Section:
    """A part of the report: a table of checks, figures and prose (markdown)."""

    title: str
    anchor: str
    checks: list[Check] = field(default_factory=list)
    figures: list[tuple[str, str]] = field(default_factory=list)
    """(file name relative to the report, caption)."""
    text: str = ""
    seconds: float = 0.0
