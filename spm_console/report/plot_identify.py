"""The identification experiment's plot: per joint, reference, measured and fitted positions,
and the model's error, with the held-out part shaded. Matplotlib with the Agg backend.
Degrees, seconds."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from spm_console.core.servo.experiment import Excitation, ExperimentFit

F = NDArray[np.float64]


def plot_experiment(ex: Excitation, t: F, measured_deg: F, fit: ExperimentFit,
                    path: str | Path) -> Path:
    """Save a 3×2 figure: θ*, θ measured and the fitted model per joint; model − measured."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tt = np.asarray(t, float) - float(t[0])
    ref = ex.reference_deg[: len(t)]
    model = fit.assessment.model_deg
    held = ex.mask("held-out")[: len(t)]
    fig, axes = plt.subplots(3, 2, figsize=(12, 8), sharex=True)
    for j in range(3):
        a, b = axes[j]
        a.step(tt, ref[:, j], where="post", lw=0.8, label="θ* sent")
        a.plot(tt, measured_deg[:, j], ".", ms=2, label="θ measured")
        a.plot(tt, model[:, j], lw=0.8, label="model")
        b.plot(tt, model[:, j] - measured_deg[:, j], lw=0.8)
        for ax in (a, b):
            if held.any():
                ax.axvspan(tt[held][0], tt[held][-1], color="0.9", zorder=0)
        a.set_ylabel(f"θ{j + 1} (deg)")
        b.set_ylabel("model − θ (deg)")
    axes[0, 0].legend(loc="upper right", fontsize=8)
    axes[0, 1].set_title("held-out part shaded")
    s = fit.shared
    fig.suptitle(f"identified ωn = {s.p:.2f} rad/s, ζ = {s.zeta:.3f}, delay "
                 f"{1e3 * s.delay_s:.1f} ms; held-out RMS {fit.assessment.held_out_rms_deg:.3f}°")
    axes[2, 0].set_xlabel("t (s)")
    axes[2, 1].set_xlabel("t (s)")
    fig.tight_layout()
    out = Path(path)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
