"""The Execute step's preview: the run the wrist is about to make, made first on its twin in
simulated time (:mod:`spm_console.services.preview`), in words and as a "predicted vs
planned" plot, shown under the plan and before "Execute the plan?" is answered."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from spm_console.formatting import fmt_vec
from spm_console.tui.widgets.plot import PlotView, joint_series

if TYPE_CHECKING:
    from spm_console.core.plan import Plan
    from spm_console.services.preview import Preview

#: A preview stays valid for the same plan while the wrist rests within this of where the
#: twin started, deg (the emulated encoder's resolution is 0.088°).
SAME_START_DEG = 0.2


def preview_lines(pv: Preview) -> list[str]:
    """The predicted run in a few lines (the CLI's ``execute --preview`` figures)."""
    ex = pv.run.execution
    st = ex.stats
    wrist = "physical wrist" if pv.plant == "physical" else "ideal servos (eq. 27)"
    head = "completes" if ex.ok else f"STOPS (exit code {int(ex.exit_code)})"
    lines = [f"Preview on the twin ({wrist}, {pv.simulated_s:.2f} s simulated in "
             f"{pv.wall_s:.1f} s): the run {head}: {ex.message}"]
    if st.tracking_rms_per_joint_deg and st.model is not None:
        lines.append(f"  tracking of the servo model: RMS {fmt_vec(st.tracking_rms_per_joint_deg, 3)}°,"
                     f" max {fmt_vec(st.model.max_per_joint_deg, 3)}°")
    if pv.final_error_deg is not None:
        lines.append(f"  final error against the goal: {fmt_vec(pv.final_error_deg, 3)}°")
    if math.isfinite(pv.min_margin_deg):
        lines.append(f"  closest to the edge of P′: {pv.min_margin_deg:.2f}° (L∞); closest links:"
                     f" {pv.min_link_mm:.1f} mm (2δ = {pv.link_limit_mm:.1f} mm)")
    if pv.peak_current_a is not None:
        lines.append(f"  peak motor current: {fmt_vec(pv.peak_current_a, 2)} A per joint")
    return lines


def still_valid(pv: Preview, plan: Plan, here_deg: object) -> bool:
    """Whether ``pv`` previews executing ``plan`` from ``here_deg`` (the same plan object, the
    wrist within :data:`SAME_START_DEG` of where the twin started)."""
    if pv.plan is not plan or pv.start_deg is None or here_deg is None:
        return False
    here = np.asarray(here_deg, float)
    return bool(np.all(np.isfinite(here))
                and np.abs(here - pv.start_deg).max() <= SAME_START_DEG)


def draw_preview(view: PlotView, pv: Preview) -> None:
    """The twin's θ against the planned θ* over the whole predicted execution."""
    track = pv.track
    if track is None or len(track.t_s) < 2:
        return
    series = joint_series("θ* ", track.planned_deg, faint=True)
    series += joint_series("θ ", track.predicted_deg)
    view.plot("preview: planned θ* (dots), predicted θ on the twin [deg]", track.t_s, series)
