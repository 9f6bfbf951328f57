"""Pareto plot of a design sweep: every design built on two figures of merit, the designs
no other beats on both marked and joined (matplotlib, Agg, no pyplot)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def plot_pareto(cols: dict[str, list[Any]], x: str, y: str, front: np.ndarray,
                out: str | Path, title: str = "") -> Path:
    """Draw the designs of ``cols`` on ``x``/``y`` with the ``front`` rows marked."""
    out = Path(out)
    ok = np.asarray(cols["ok"], bool)
    X = np.asarray([np.nan if v is None else v for v in cols[x]], float)
    Y = np.asarray([np.nan if v is None else v for v in cols[y]], float)
    fig = Figure(figsize=(7.5, 5.5), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    ax.plot(X[ok], Y[ok], ".", color="0.6", ms=5, label=f"designs ({int(ok.sum())})")
    ax.plot(X[front], Y[front], "o-", color="tab:red", ms=5, lw=1.2,
            label=f"Pareto front ({len(front)})")
    for r in front:
        ax.annotate(str(cols["index"][r]), (X[r], Y[r]), textcoords="offset points",
                    xytext=(4, 4), fontsize=7)
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best")
    if title:
        ax.set_title(title)
    fig.savefig(out, dpi=120)
    return out
