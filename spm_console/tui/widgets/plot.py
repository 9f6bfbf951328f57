"""A line plot drawn with plotext to the widget's size (references, positions, velocities).

The legend is a line of coloured labels above the canvas (plotext's own legend box
would hide the start of the curves).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rich.text import Text
from textual.widgets import Static

F = NDArray[np.float64]

#: At most this many points per series are drawn (evenly decimated).
MAX_POINTS = 400
#: One colour per joint (plotext and Rich both know these names).
JOINT_COLORS = ("red", "green", "blue")


@dataclass(frozen=True)
class Series:
    label: str
    y: Any
    """Values (deg, deg/s …), one per x; NaN gaps are skipped."""
    color: str = "red"
    """plotext / Rich colour name."""
    faint: bool = False
    """Draw as dots (references, models) rather than a solid braille line."""


def joint_series(name: str, values: Any, faint: bool = False) -> list[Series]:
    """Three series (one per joint column of ``values``), coloured by joint."""
    v = np.asarray(values, float)
    return [Series(f"{name}{i + 1}", v[:, i], JOINT_COLORS[i], faint) for i in range(3)]


class PlotView(Static):
    """Call :meth:`plot` with x and labelled series; it redraws on resize."""

    DEFAULT_CLASSES = "plot"

    def __init__(self, title: str = "", *, id: str | None = None) -> None:
        super().__init__("", id=id)
        self._title = title
        self._x: F = np.zeros(0)
        self._series: list[Series] = []
        self._xlabel = ""

    def plot(self, title: str, x: Any, series: Sequence[Series], xlabel: str = "t [s]") -> None:
        self._title = title
        self._x = np.asarray(x, float)
        self._series = list(series)
        self._xlabel = xlabel
        self._draw()

    def on_resize(self) -> None:
        self._draw()

    def _draw(self) -> None:
        w, h = self.content_size.width, self.content_size.height
        if w < 20 or h < 6 or not self._series or len(self._x) < 2:
            self.update(Text(self._title or "", style="dim"))
            return
        self.update(render_plot(self._title, self._x, self._series, w, h, self._xlabel))


def legend(title: str, series: Sequence[Series]) -> Text:
    out = Text(title, style="bold")
    out.append("   ")
    for s in series:
        out.append(("· " if s.faint else "━ ") + s.label + "  ", style=s.color)
    return out


def render_plot(title: str, x: F, series: Sequence[Series], width: int, height: int,
                xlabel: str = "") -> Text:
    """Title and legend line, then the plotext canvas, as Rich text (call on the UI thread
    only: plotext keeps one global figure)."""
    import plotext as plt

    plt.terminal.limit(False, False)  # the widget's size, not the terminal's, bounds the plot
    step = max(1, len(x) // MAX_POINTS)
    xs = np.asarray(x, float)[::step]
    fig = plt.figure
    fig.clear()
    fig.plot_size(width, height - 1)
    fig.theme("dark")
    for s in series:
        y = np.asarray(s.y, float)[::step]
        ok = np.isfinite(y)
        if ok.sum() < 2:
            continue
        marker = plt.marker("•" if s.faint else "braille", pixel=s.color)
        sig = fig.signal(xs[ok].tolist(), y[ok].tolist(), marker=marker)
        fig.draw(sig if s.faint else sig.lines())
    fig.legend(active=False)
    if xlabel:
        fig.label(xlabel)
    out = legend(title, series)
    out.append("\n")
    out.append_text(Text.from_ansi(str(fig.build())))
    return out
