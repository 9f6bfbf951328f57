"""Whether a record asks for a higher order: a third-order servo's record does, a second
order's does not, and the lag's time constant is recovered."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.core.servo.experiment import excitation
from spm_console.core.servo.order import check_order, simulate

TS = 0.02
HOME = np.array([135.0, 135.0, 135.0])


def _record(tau: float):  # type: ignore[no-untyped-def]
    ex = excitation(HOME, TS, 6.0, 120.0)
    t = 7.0 + np.arange(len(ex.reference_deg)) * TS
    meas = simulate(40.0, 0.8, tau, 0.003, TS, ex.reference_deg, HOME)
    return ex, t, meas


def test_the_second_order_of_a_second_order_servo_is_enough() -> None:
    ex, t, meas = _record(0.0)
    c = check_order(t, ex.reference_deg, meas, ex.mask("fit"), ex.mask("held-out"), 38.0, 0.75,
                    0.003, HOME)
    assert c.held_out_rms_2nd_deg < 1e-4 and not c.asks


def test_a_lagging_servo_asks_for_a_third_pole() -> None:
    ex, t, meas = _record(0.03)
    c = check_order(t, ex.reference_deg, meas, ex.mask("fit"), ex.mask("held-out"), 38.0, 0.75,
                    0.003, HOME)
    assert c.asks and c.tau_s == pytest.approx(0.03, rel=1e-3)
    assert c.held_out_rms_3rd_deg < 1e-4 < 0.01 < c.held_out_rms_2nd_deg


def test_the_second_order_simulation_is_the_identifications_own() -> None:
    """τ = 0 is the identified structure: the same samples as the identification's filter of
    the sampled model with its delay (an independent implementation)."""
    from spm_console.core.servo.identify import response_uniform
    from spm_console.core.servo.model import Dynamics

    ex = excitation(HOME, TS, 6.0, 120.0)
    for d in (0.0, 0.003, 0.0125):
        ours = simulate(41.0, 0.73, 0.0, d, TS, ex.reference_deg, HOME)
        theirs = response_uniform(Dynamics(41.0, 0.73, d), TS, ex.reference_deg, HOME)
        np.testing.assert_allclose(ours, theirs, atol=1e-9)
