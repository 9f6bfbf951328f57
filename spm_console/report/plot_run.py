"""Figure of an executed run, like the paper's Figs. 7-10 (matplotlib, Agg, no pyplot).

Top row, one panel per joint: reference θ* (steps), the model's simulated θ and
the measured θ. Bottom row: the model's velocity, the Kalman estimate and, faint,
the finite differences of the measured positions. Stops are marked. Degrees,
deg/s, seconds.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from spm_console.motion.logs.runlog import RunData


def plot_run(run: RunData, out: str | Path, title: str | None = None) -> Path:
    """Draw ``run`` into ``out`` (.png/.svg/.pdf); returns the path."""
    out = Path(out)
    t = run.columns.get("t", np.zeros(0))
    fig = Figure(figsize=(13, 6.5), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 3, sharex=True)
    ref, meas, pred = run.vec("ref"), run.vec("meas"), run.vec("pred")
    pvel, vel, fd = run.vec("pred_vel"), run.vec("vel"), run.vec("fd_vel")
    stops = [e for e in run.events if e.get("event") == "stop"]
    for i in range(3):
        ax = axes[0, i]
        ax.step(t, ref[:, i], where="post", color="0.55", lw=1.0, label="reference θ*")
        ax.plot(t, pred[:, i], color="tab:blue", lw=1.4, label="simulated (model)")
        ax.plot(t, meas[:, i], ".", color="tab:red", ms=2.5, label="measured")
        ax.set_title(f"joint {i + 1}")
        ax.set_ylabel("θ (deg)")
        ax = axes[1, i]
        ax.plot(t, fd[:, i], color="tab:orange", lw=0.7, alpha=0.45, label="finite differences")
        ax.plot(t, pvel[:, i], color="tab:blue", lw=1.4, label="simulated (model)")
        ax.plot(t, vel[:, i], color="tab:green", lw=1.2, label="Kalman estimate")
        ax.set_ylabel("θ̇ (deg/s)")
        ax.set_xlabel("t (s)")
        for row in (0, 1):
            for e in stops:
                t_stop = e.get("t", 0.0)
                if isinstance(t_stop, int | float):
                    axes[row, i].axvline(float(t_stop), color="k", ls="--", lw=0.8)
            axes[row, i].grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=8, loc="best")
    axes[1, 0].legend(fontsize=8, loc="best")
    m = run.meta
    head = title or (f"{m.get('run', run.path.name)} — {m.get('kind', '')}: "
                     f"{m.get('outcome', '')} {m.get('message', '')}")
    fig.suptitle(head[:140], fontsize=10)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    return out
