"""The console's identification experiment (step 1, key i): what the operator is asked, the
blocking work (experiment, fit, the identified profile written beside the profile in use, the
plot into the run's folder) and its result. The profile in use is not changed here: the
operator is asked next whether to restart the console on the identified one."""

from __future__ import annotations

from pathlib import Path

from spm_console.config.models import servo_model_of
from spm_console.config.schema import DEFAULT_PROFILE
from spm_console.core.plan_rules import MAX_REFERENCE_STEP_DEG
from spm_console.errors import BadInputError
from spm_console.report.plot_identify import plot_experiment
from spm_console.services.identify.experiment import (
    SPEED_SHARE,
    STEP_MARGIN_DEG,
    experiment_in_session,
    fit_experiment,
    identified_servo,
)
from spm_console.services.identify.report import fit_lines, identified_text
from spm_console.services.session import SampleCallback, Session
from spm_console.store.identified_profiles import identified_path, write_beside, write_new
from spm_console.tui.messages import IdentifyDone

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
            "fitted and a new profile with it is written beside the profile in use "
            "(NAME.identified-TIME.toml); you are then asked whether to use it.")


def identify_blocking(session: Session, profile_path: Path | None,
                      on_sample: SampleCallback) -> IdentifyDone:
    """Run the experiment, fit it, write the identified profile beside the profile file in
    use (into the run's folder when that folder is not writable, saying why) and the plot
    into the run's folder (worker thread)."""
    run = experiment_in_session(session, on_sample)
    if run.t is None or run.reference_deg is None or run.measured_deg is None:
        return IdentifyDone(run.execution, None, None, "")
    folder = Path(str(run.execution.log_dir))
    fit = fit_experiment(session.profile, run)
    servo = identified_servo(session.profile, fit, str(folder))
    assert servo.identified is not None
    date = servo.identified.date
    source = profile_path if profile_path is not None else DEFAULT_PROFILE
    text, _ = identified_text(source, servo, str(identified_path(source, date)))
    where = ""
    try:
        out = write_beside(source, text, date)
    except BadInputError as exc:
        out = write_new(folder / identified_path(source, date).name, text)
        where = f" ({exc.message}: written into the run's folder instead)"
    plot = plot_experiment(run.excitation, run.t, run.measured_deg, fit, folder / PLOT_NAME)
    a = fit.assessment
    summary = (f"identified: ωn = {servo.p:.2f} rad/s, ζ = {servo.zeta:.3f}, delay "
               f"{1e3 * servo.delay_s:.1f} ms; held-out RMS {a.held_out_rms_deg:.3f}°; the "
               "whole result and the profile written are on this step")
    lines = (f"Identified profile written: {out}{where}",
             *fit_lines(run, fit, servo, session.profile.servo), f"plot: {plot}")
    return IdentifyDone(run.execution, out, plot, summary, lines)
