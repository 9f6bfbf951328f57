"""The identification experiment's result as every front end reports it: the figures of the
fit (a JSON record and the lines of text ``identify --experiment`` prints and the console
shows), and the identified profile's text made from the profile file in use."""

from __future__ import annotations

from pathlib import Path

from spm_console.config.schema import Profile, Servo
from spm_console.core.servo.experiment import ExperimentFit
from spm_console.core.servo.identify import IdentifyResult
from spm_console.core.servo.order import OrderCheck
from spm_console.errors import BadInputError
from spm_console.safe_io import MB, read_text
from spm_console.services.identify.experiment import ExperimentRun, identified_profile

#: Largest profile file read to write its identified copy.
MAX_PROFILE_TEXT = 1 * MB


def identified_text(profile_path: Path, servo: Servo, written_as: str) -> tuple[str, Profile]:
    """The profile file ``profile_path`` with the identified ``servo`` (every other line kept)
    and the profile it parses to (``written_as`` names it in a refusal)."""
    text = read_text(profile_path, "profile", MAX_PROFILE_TEXT, BadInputError)
    return identified_profile(text, servo, written_as)


def _fit_dict(r: IdentifyResult) -> dict[str, float]:
    return {"wn_radps": r.p, "wn_std": r.p_std, "zeta": r.zeta, "zeta_std": r.zeta_std,
            "delay_s": r.delay_s, "rms_deg": r.rms_deg}


def fit_data(run: ExperimentRun, fit: ExperimentFit, servo: Servo) -> dict[str, object]:
    """The fit as JSON (``identify --experiment --json``; the front end adds what it wrote)."""
    a, s = fit.assessment, fit.shared
    return {
        "outcome": run.execution.outcome, "exit_code": 0, "log_dir": str(run.execution.log_dir),
        "model": _fit_dict(s),
        "joints": [_fit_dict(j) for j in fit.joints],
        "fit_rms_deg": a.fit_rms_deg, "held_out_rms_deg": a.held_out_rms_deg,
        "held_out_max_deg": a.held_out_max_deg, "linear_range_deg": servo.linear_range_deg,
        "saturated": a.saturated, "residual_bound_deg": servo.residual_bound_deg,
        "blocks": [{"kind": b.block.kind, "part": b.block.part, "size": b.block.size,
                    "reached_deg": b.reached_deg, "rms_deg": b.rms_deg, "max_deg": b.max_deg}
                   for b in a.blocks],
        "motion_s": run.excitation.duration_s,
        "load_deg_per_nm": servo.load_deg_per_nm, "coulomb_deg": servo.coulomb_deg,
        "order": None if fit.order is None else {
            "third_pole_tau_s": fit.order.tau_s, "asks": fit.order.asks,
            "held_out_rms_2nd_deg": fit.order.held_out_rms_2nd_deg,
            "held_out_rms_3rd_deg": fit.order.held_out_rms_3rd_deg},
    }


def fit_lines(run: ExperimentRun, fit: ExperimentFit, servo: Servo, before: Servo) -> list[str]:
    """The fit in words, one line per figure (the front end adds what it wrote)."""
    a, s = fit.assessment, fit.shared
    return [
        f"identified: ωn = {s.p:.2f} ± {s.p_std:.2f} rad/s, ζ = {s.zeta:.3f} ± {s.zeta_std:.3f}, "
        f"delay {1e3 * s.delay_s:.1f} ms (the profile had p = {servo_words(before)})",
        *(f"  joint {i + 1} alone: ωn = {j.p:.2f} rad/s, ζ = {j.zeta:.3f}, delay "
          f"{1e3 * j.delay_s:.1f} ms, RMS {j.rms_deg:.3f}°" for i, j in enumerate(fit.joints)),
        f"model against measurement: fitted part RMS {a.fit_rms_deg:.3f}°; held-out part RMS "
        f"{a.held_out_rms_deg:.3f}°, max {a.held_out_max_deg:.3f}°",
        (f"load: {servo.load_deg_per_nm} deg per N·m of the weight's holding torque, "
         f"Coulomb friction {servo.coulomb_deg}°" if servo.load_deg_per_nm is not None
         else "load: none found"),
        *([] if fit.order is None else [order_words(fit.order)]),
        f"linear range: {servo.linear_range_deg:.2f}° of |θ* − θ|"
        + ("" if a.saturated else " at least (the experiment never saturated the servo)"),
        f"{run.excitation.duration_s:.1f} s of motion; log: {run.execution.log_dir}",
    ]


def order_words(o: OrderCheck) -> str:
    """The order check in words."""
    verdict = ("the data ask for it (the planner keeps the second order; the residual bound "
               "covers the rest)" if o.asks else "the data do not ask for a higher order")
    return (f"order: a third pole (lag {1e3 * o.tau_s:.1f} ms) gives held-out RMS "
            f"{o.held_out_rms_3rd_deg:.3f}° against {o.held_out_rms_2nd_deg:.3f}° for the "
            "second order refitted alike (the load's offset taken off the reference, the "
            f"delay held: not the identified model's held-out figure above): {verdict}")


def servo_words(sv: Servo) -> str:
    """A servo model in words."""
    return f"{sv.p:g} rad/s" + ("" if sv.zeta == 1.0 else f", ζ = {sv.zeta:g}")
