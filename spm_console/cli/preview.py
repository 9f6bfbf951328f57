"""``execute --preview``: the run the wrist is about to make, on its twin in simulated time
(:mod:`spm_console.services.preview`); nothing moves on the wrist. Exit code: the predicted
run's (0 when it completes), so ``execute --preview && execute`` moves only what the twin
completed. Degrees, mm, seconds."""

from __future__ import annotations

import argparse
import math
from typing import Any

from spm_console.cli.common import console_plant, emit, info, output_may_be_gone, with_plant
from spm_console.config.load import load_profile
from spm_console.core.plan import Plan
from spm_console.formatting import fmt_vec
from spm_console.services.oneshot import RunRequest
from spm_console.services.preview import Preview, preview_execute


def preview_of(args: argparse.Namespace, plan: Plan, req: RunRequest) -> Preview:
    """The preview of ``execute`` as ``args`` and ``req`` ask for it, on the profile's twin:
    ``--plant`` when given, the profile's ``[plant] model`` when it names one, else the
    physical wrist."""
    base = load_profile(args.profile)
    twin = with_plant(base, console_plant(base, args.plant))
    return preview_execute(twin, plan, req, source=str(args.plan))


def _num(x: float) -> float | None:
    return x if math.isfinite(x) else None


def report_preview(args: argparse.Namespace, pv: Preview) -> int:
    ex = pv.run.execution
    st = ex.stats
    model = st.model
    homing = pv.run.homing
    data: dict[str, Any] = {
        "preview": True, "outcome": ex.outcome, "exit_code": int(ex.exit_code),
        "message": ex.message, "plant": pv.plant,
        "start_deg": pv.start_deg, "final_deg": ex.final_deg,
        "final_error_deg": pv.final_error_deg,
        "tracking_rms_per_joint_deg": list(st.tracking_rms_per_joint_deg),
        "tracking_max_per_joint_deg": None if model is None else list(model.max_per_joint_deg),
        "min_margin_deg": _num(pv.min_margin_deg), "min_link_mm": _num(pv.min_link_mm),
        "link_limit_mm": pv.link_limit_mm, "simulated_s": pv.simulated_s, "wall_s": pv.wall_s,
        "log_dir": str(ex.log_dir) if ex.log_dir else None,
        "homing": None if homing is None else {
            "outcome": homing.execution.outcome,
            "log_dir": str(homing.execution.log_dir or "") or None},
        "plan": str(args.plan), "stats": st.to_dict(),
    }
    wrist = "the physical wrist" if pv.plant == "physical" else "ideal servos (eq. 27)"
    lines = [f"preview on the twin ({wrist}; {pv.simulated_s:.2f} s simulated in "
             f"{pv.wall_s:.2f} s): {ex.outcome}: {ex.message}"]
    if st.tracking_rms_per_joint_deg and model is not None:
        lines.append(f"predicted tracking of the servo model: RMS "
                     f"{fmt_vec(st.tracking_rms_per_joint_deg, 3)}°, max "
                     f"{fmt_vec(model.max_per_joint_deg, 3)}° per joint")
    if pv.final_error_deg is not None:
        lines.append(f"final error against the plan's goal: {fmt_vec(pv.final_error_deg, 3)}°")
    if math.isfinite(pv.min_margin_deg):
        lines.append(f"closest to the edge of the certified set P′: {pv.min_margin_deg:.3f}° "
                     f"(L∞); closest links: {pv.min_link_mm:.1f} mm (2δ = "
                     f"{pv.link_limit_mm:.1f} mm)")
    lines.append("nothing moved on the wrist" + (f"; log: {ex.log_dir} (preview)"
                                                  if ex.log_dir else ""))
    with output_may_be_gone():
        emit(args, data, "\n".join(lines))
        if not ex.ok:
            info(f"the preview stopped: {ex.message}")
    return int(ex.exit_code)
