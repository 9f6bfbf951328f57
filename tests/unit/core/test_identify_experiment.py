"""The identification experiment's fit: a known linear model (ωn, ζ, delay) is recovered
exactly from its own exact response to the excitation, and the assessment splits the record
into its parts and blocks."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.core.servo.experiment import MAX_MOTION_S, assess, excitation, fit_record
from spm_console.core.servo.identify import response
from spm_console.core.servo.model import Dynamics

TS = 0.02
HOME = np.array([135.0, 135.0, 135.0])


def _record(dyn: Dynamics, step: float = 6.0, speed: float = 120.0):  # type: ignore[no-untyped-def]
    ex = excitation(HOME, TS, step, speed)
    t = 1000.0 + np.arange(len(ex.reference_deg)) * TS  # a log's clock does not start at 0
    meas = response(dyn, dyn.delay_s, t - t[0], ex.reference_deg, HOME)
    return ex, t, meas


def test_the_excitation_is_bounded_and_made_of_two_parts() -> None:
    ex = excitation(HOME, TS, 9.0, 200.0)
    assert ex.duration_s <= MAX_MOTION_S
    steps = np.abs(np.diff(ex.reference_deg, axis=0))
    assert steps.max() <= 9.0 + 1e-12
    assert np.abs(ex.reference_deg - HOME).max() <= 9.0 + 1e-12
    fit, held = ex.mask("fit"), ex.mask("held-out")
    assert fit.sum() > held.sum() > 0 and not (fit & held).any()
    assert np.flatnonzero(fit).max() < np.flatnonzero(held).min()  # fitted first, then held out
    np.testing.assert_allclose(ex.reference_deg[[0, -1]], [HOME, HOME])
    # the joints move together, joint 2 the other way
    d = ex.reference_deg - HOME
    np.testing.assert_allclose(d[:, 1], -d[:, 0])
    np.testing.assert_allclose(d[:, 2], d[:, 0])


@pytest.mark.parametrize("dyn", [Dynamics(43.0, 0.79, 0.0035), Dynamics(32.22, 1.0, 0.0),
                                 Dynamics(60.0, 1.4, 0.011)])
def test_a_known_linear_model_is_recovered_exactly(dyn: Dynamics) -> None:
    ex, t, meas = _record(dyn)
    fit = fit_record(ex, t, ex.reference_deg, meas)
    s = fit.shared
    assert s.p == pytest.approx(dyn.wn, rel=1e-6)
    assert s.zeta == pytest.approx(dyn.zeta, rel=1e-6)
    assert s.delay_s == pytest.approx(dyn.delay_s, abs=1e-7)
    for j in fit.joints:
        assert j.p == pytest.approx(dyn.wn, rel=1e-6) and j.zeta == pytest.approx(dyn.zeta, rel=1e-6)
    a = fit.assessment
    assert a.held_out_max_deg < 1e-6 and a.fit_rms_deg < 1e-6
    assert not a.saturated
    assert a.linear_range_deg == pytest.approx(np.abs(ex.reference_deg - meas).max(), rel=1e-9)


def test_a_saturating_servo_is_seen_and_its_linear_range_measured() -> None:
    """The same servo whose drive saturates: its speed cannot pass 150°/s (a rate limit on
    the exact response, integrated at 0.5 ms). Blocks that ask for more are marked, and the
    linear range stops below them."""
    dyn = Dynamics(43.0, 0.85)
    ex = excitation(HOME, TS, 9.0, 220.0)
    h, sub = 5e-4, round(TS / 5e-4)
    A = np.array([[0.0, 1.0], [-dyn.wn ** 2, -2 * dyn.zeta * dyn.wn]])
    x = np.vstack([HOME, np.zeros(3)])
    meas = []
    for r in ex.reference_deg:
        meas.append(x[0].copy())
        for _ in range(sub):
            acc = A[1, 0] * x[0] + A[1, 1] * x[1] + dyn.wn ** 2 * r
            v = np.clip(x[1] + h * acc, -150.0, 150.0)
            x = np.vstack([x[0] + h * v, v])
    meas_a = np.array(meas)
    t = np.arange(len(meas_a)) * TS
    fit = fit_record(ex, t, ex.reference_deg, meas_a)
    a = fit.assessment
    assert a.saturated
    fast = [b for b in a.blocks if b.reached_deg > a.linear_range_deg]
    assert fast and all(b.block.kind in ("step", "ramp", "chirp") for b in fast)
    assert a.linear_range_deg < np.abs(ex.reference_deg - meas_a).max()


def test_samples_whose_reply_was_lost_are_left_out_not_their_references() -> None:
    """A lost reply leaves its row's measurement NaN; the reference sent then still acts."""
    dyn = Dynamics(43.0, 0.79, 0.0035)
    ex, t, meas = _record(dyn)
    meas[[40, 41, 300, 700]] = np.nan
    a = assess(ex, t, meas, dyn, HOME)
    assert a.held_out_max_deg < 1e-9 and a.fit_rms_deg < 1e-9
    fit = fit_record(ex, t, ex.reference_deg, meas)
    assert fit.shared.p == pytest.approx(dyn.wn, rel=1e-6)


@pytest.mark.parametrize("dyn", [Dynamics(40.0, 0.8), Dynamics(40.0, 0.8, 0.007),
                                 Dynamics(32.22, 1.0, 0.05), Dynamics(50.0, 1.5, 0.1)])
def test_the_grids_filter_is_the_event_response_on_uniform_samples(dyn: Dynamics) -> None:
    """The fit's coarse grid runs the sampled model as a linear filter (delays of whole and
    part samples); on uniform samples it is the exact event-by-event response."""
    from spm_console.core.servo.identify import response_uniform

    rng = np.random.default_rng(0)
    ref = 135.0 + np.cumsum(rng.normal(size=(300, 3)), axis=0)
    t = np.arange(300) * TS
    np.testing.assert_allclose(response_uniform(dyn, TS, ref, ref[0]),
                               response(dyn, dyn.delay_s, t, ref, ref[0]), atol=1e-9)

