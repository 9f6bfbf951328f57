"""Plan plots like the paper's Figs. 7–10: references, positions and velocities per joint.

Matplotlib with the Agg backend (no display needed). Degrees, deg/s, seconds.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from spm_console.core.plan import Plan
from spm_console.core.servo.model import simulate_continuous

F = NDArray[np.float64]


def plot_plan(plan: Plan, path: str | Path, measured_deg: F | None = None,
              measured_t: F | None = None, title: str = "") -> Path:
    """Save a 3×2 figure: θ*, θ (samples and continuous) per joint; θ̇ per joint."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = plan.N
    ts = plan.Ts
    t = np.arange(n + 1) * ts
    x0 = np.column_stack([plan.position_deg[0], plan.velocity_degps[0]])
    cont = simulate_continuous(plan.model.dynamics, ts, x0, plan.reference_deg, 10)
    vmax = plan.options.vmax_degps if plan.options is not None else None
    fig, axes = plt.subplots(3, 2, figsize=(11, 8), sharex=True)
    for i in range(3):
        ax = axes[i, 0]
        ax.step(t, plan.reference_deg[:, i], where="post", color="tab:gray", lw=1.0,
                label="reference θ*")
        ax.plot(cont[0], cont[1][:, i, 0], color="tab:blue", lw=0.8, alpha=0.6,
                label="model, continuous")
        ax.plot(t, plan.position_deg[:, i], ".", color="tab:blue", ms=2.5, label="model θ(k)")
        if measured_deg is not None and measured_t is not None:
            ax.plot(measured_t, measured_deg[:, i], color="tab:red", lw=0.8, label="measured")
        ax.set_ylabel(f"θ{i + 1} (deg)")
        ax.grid(alpha=0.3)
        av = axes[i, 1]
        av.plot(cont[0], cont[1][:, i, 1], color="tab:green", lw=0.8, alpha=0.6,
                label="continuous")
        av.plot(t, plan.velocity_degps[:, i], ".", color="tab:green", ms=2.5, label="θ̇(k)")
        if vmax:
            for sgn in (1, -1):
                av.axhline(sgn * float(vmax), color="tab:red", ls="--", lw=0.8)
        av.set_ylabel(f"θ̇{i + 1} (deg/s)")
        av.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, loc="best")
    axes[0, 1].legend(fontsize=7, loc="best")
    axes[2, 0].set_xlabel("t (s)")
    axes[2, 1].set_xlabel("t (s)")
    fig.suptitle(title or f"{plan.kind} plan: N = {n} ({n * ts:.2f} s), cost {plan.cost:.4g}")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
