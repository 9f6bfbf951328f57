"""The identified [servo] section built from an experiment's fit."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from spm_console.config.load import load_profile
from spm_console.core.servo.experiment import excitation, fit_record
from spm_console.core.servo.identify import response
from spm_console.core.servo.model import Dynamics
from spm_console.errors import SolverError
from spm_console.services.identify.experiment import identified_servo
from tests.support.paths import ROOT

HOME = np.array([135.0, 135.0, 135.0])


def _record(dyn: Dynamics):  # type: ignore[no-untyped-def]
    ex = excitation(HOME, 0.02, 6.0, 120.0)
    t = np.arange(len(ex.reference_deg)) * 0.02
    return ex, t, response(dyn, dyn.delay_s, t, ex.reference_deg, HOME)


def test_a_model_no_profile_can_hold_is_a_solver_error_not_a_crash() -> None:
    """A held-out error above the 10° a profile's residual bound accepts: refused with the
    key named (exit 7), never a validation traceback."""
    dyn = Dynamics(43.0, 0.79, 0.0035)
    ex, t, meas = _record(dyn)
    fit = fit_record(ex, t, ex.reference_deg, meas)
    prof = load_profile(ROOT / "profiles" / "agile_wrist.toml")
    assert identified_servo(prof, fit, "run").zeta == pytest.approx(0.79, abs=1e-4)
    broken = replace(fit, assessment=replace(fit.assessment, held_out_max_deg=12.0))
    with pytest.raises(SolverError, match="residual_bound_deg"):
        identified_servo(prof, broken, "run")


def test_a_load_below_the_written_precision_is_no_load_not_a_refusal() -> None:
    """A fitted load that rounds to zero (a servo with no load to speak of) is written as none;
    it was refused as an invalid [servo] section (exit 7)."""
    from spm_console.core.servo.load import LoadModel

    dyn = Dynamics(43.0, 0.79, 0.0035)
    ex, t, meas = _record(dyn)
    fit = fit_record(ex, t, ex.reference_deg, meas)
    prof = load_profile(ROOT / "profiles" / "agile_wrist.toml")
    tiny = replace(fit, load=LoadModel(np.array([1e-6]), 0.01))
    servo = identified_servo(prof, tiny, "run")
    assert servo.load_deg_per_nm is None and servo.coulomb_deg == pytest.approx(0.01)
