"""The load's offset is identified with the dynamics: a record made by a known loaded model
(weight offset along given holding torques, Coulomb friction against the model's speed) gives
back its ωn, ζ, delay, deg per N·m and friction."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.core.servo.experiment import excitation, fit_record
from spm_console.core.servo.identify import response
from spm_console.core.servo.load import LoadModel
from spm_console.core.servo.load_fit import model_velocity
from spm_console.core.servo.model import Dynamics

TS = 0.02
HOME = np.array([135.0, 135.0, 135.0])


def _loaded_record(dyn: Dynamics, load: LoadModel):  # type: ignore[no-untyped-def]
    ex = excitation(HOME, TS, 6.0, 120.0)
    t = 50.0 + np.arange(len(ex.reference_deg)) * TS
    ref = ex.reference_deg
    # a holding torque that changes with the pose (N·m), as the weight's does
    hold = 0.2 + 0.05 * np.sin(np.radians(8.0) * (ref - HOME) * 10.0)
    d = load.offset_deg(hold[:, :, None], model_velocity(dyn, t, ref, HOME))
    meas = response(dyn, dyn.delay_s, t - t[0], ref - d, HOME - d[0])
    return ex, t, ref, meas, hold


@pytest.mark.parametrize(("k", "c"), [(1.4, 0.09), (0.8, 0.0), (2.5, 0.2)])
def test_a_known_loaded_model_is_recovered(k: float, c: float) -> None:
    dyn = Dynamics(40.0, 0.75, 0.002)
    ex, t, ref, meas, hold = _loaded_record(dyn, LoadModel(np.array([k]), c))
    fit = fit_record(ex, t, ref, meas, hold)
    assert fit.load is not None
    assert fit.shared.p == pytest.approx(dyn.wn, rel=1e-3)
    assert fit.shared.zeta == pytest.approx(dyn.zeta, rel=1e-3)
    assert fit.load.moments_deg[0] == pytest.approx(k, rel=2e-2)
    assert fit.load.coulomb_deg == pytest.approx(c, abs=5e-3)
    # and the loaded model explains the record, held-out part included
    assert fit.assessment.held_out_rms_deg < 5e-3


def test_without_a_load_the_linear_fit_misses_what_the_loaded_one_explains() -> None:
    dyn = Dynamics(40.0, 0.75, 0.002)
    ex, t, ref, meas, hold = _loaded_record(dyn, LoadModel(np.array([1.4]), 0.09))
    plain = fit_record(ex, t, ref, meas)
    loaded = fit_record(ex, t, ref, meas, hold)
    assert plain.load is None
    assert loaded.assessment.held_out_rms_deg < 0.2 * plain.assessment.held_out_rms_deg
