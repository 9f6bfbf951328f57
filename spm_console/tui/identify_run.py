"""The console's identification experiment (step 1, key i): what the operator is asked, the
blocking work (experiment, fit, profile and plot written into the run's folder) and its
summary. The profile in use is not changed: the new one is a file to load next time."""

from __future__ import annotations

from pathlib import Path

from spm_console.config.models import servo_model_of
from spm_console.config.schema import DEFAULT_PROFILE
from spm_console.core.plan_rules import MAX_REFERENCE_STEP_DEG
from spm_console.errors import BadInputError
from spm_console.report.plot_identify import plot_experiment
from spm_console.safe_io import MB, read_text
from spm_console.services.identify_experiment import (
    SPEED_SHARE,
    STEP_MARGIN_DEG,
    experiment_in_session,
    fit_experiment,
    identified_profile,
    identified_servo,
)
from spm_console.services.session import SampleCallback, Session
from spm_console.tui.messages import IdentifyDone

PROFILE_NAME = "identified-profile.toml"
PLOT_NAME = "identification.png"


def question(session: Session) -> str:
    """The confirmation's body: what will move, how far and how fast."""
    prof = session.profile
    vmax = prof.limits.vmax_degps
    step = min(MAX_REFERENCE_STEP_DEG - STEP_MARGIN_DEG,
               SPEED_SHARE * vmax / servo_model_of(prof).dynamics.step_peak_speed())
    return (f"The wrist makes about 18 s of small motions about home on the "
            f"{session.bus_label}: steps of up to {step:.1f}°, a chirp and ramps at up to "
            f"{SPEED_SHARE * vmax:.0f}°/s, verified like any plan. Press SPACE at any time to "
            "stop it.\nThen the servo model (ωn, ζ, delay, linear range, residual bound) is "
            f"fitted and a new profile is written into the run's log folder ({PROFILE_NAME}); "
            "the profile in use does not change.")


def identify_blocking(session: Session, profile_path: Path | None,
                      on_sample: SampleCallback) -> IdentifyDone:
    """Run the experiment, fit it, write the profile and the plot (worker thread)."""
    run = experiment_in_session(session, on_sample)
    if run.t is None or run.reference_deg is None or run.measured_deg is None:
        return IdentifyDone(run.execution, None, None, "")
    folder = Path(str(run.execution.log_dir))
    fit = fit_experiment(session.profile, run)
    servo = identified_servo(session.profile, fit, str(folder))
    source = profile_path if profile_path is not None else DEFAULT_PROFILE
    text = read_text(source, "profile", 1 * MB, BadInputError)
    out = folder / PROFILE_NAME
    new_text, _ = identified_profile(text, servo, str(out))
    out.write_text(new_text, encoding="utf-8")
    plot = plot_experiment(run.excitation, run.t, run.measured_deg, fit, folder / PLOT_NAME)
    a = fit.assessment
    summary = (f"identified: ωn = {servo.p:.2f} rad/s, ζ = {servo.zeta:.3f}, delay "
               f"{1e3 * servo.delay_s:.1f} ms; held-out RMS {a.held_out_rms_deg:.3f}°, max "
               f"{a.held_out_max_deg:.3f}°; linear range {servo.linear_range_deg:g}°"
               + (f"; load {servo.load_deg_per_nm:g} deg/(N·m) of holding torque, Coulomb "
                  f"{servo.coulomb_deg:g}°" if servo.load_deg_per_nm is not None else "")
               + ". "
               f"Profile written: {out} (start the console with --profile on it to use it); "
               f"plot: {plot}")
    return IdentifyDone(run.execution, out, plot, summary)
