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


@dataclass(frozen=True)
class ReproSettings:
    """Knobs for reduced runs (tests) vs the full reproduction."""

    quick: bool = False
    """Reduced settings: fewer verifier samples, shorter executions."""
    execute: bool = True
    """Execute the plans on the emulated bus (Figs. 7–10 equivalents)."""
    verify_samples: int = 100_000
    """Points sampled inside P by the verifier."""
    fine_grid: bool = False
    """Also plan the minimum-time pair on a 1° workspace grid (built, ~13 s and ~1 GB) and
    compare its N* with the profile's grid refined near the boundary."""
