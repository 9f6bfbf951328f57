"""Identification of p (and a delay) from step responses and runs, quantized like the servos."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.core.servo.identify import identify, response
from spm_console.core.servo.model import discretize, simulate
from spm_console.errors import BadInputError, SolverError

TICK_DEG = 360.0 / 4096
TS = 0.02

def _quantize(x: np.ndarray) -> np.ndarray:
    return np.round(x / TICK_DEG) * TICK_DEG

def _steps(n: int = 60) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(n) * TS
    ref = np.tile([100.0, 120.0, 90.0], (n, 1))
    ref[5:] = [130.0, 100.0, 95.0]
    ref[35:] = [110.0, 105.0, 120.0]
    return t, ref

def test_response_agrees_with_the_discrete_model() -> None:
    t, ref = _steps()
    m = discretize(32.22, TS)
    xs = simulate(m, np.column_stack([ref[0], np.zeros(3)]), ref)
    assert response(32.22, 0.0, t, ref, ref[0]) == pytest.approx(xs[..., 0], abs=1e-9)

@pytest.mark.parametrize("p_true", [12.0, 32.22, 80.0])
def test_recovers_p_within_2_percent_from_quantized_data(p_true: float) -> None:
    t, ref = _steps()
    rng = np.random.default_rng(7)
    clean = response(p_true, 0.0, t, ref, ref[0])
    meas = _quantize(clean + rng.normal(0.0, 0.02, clean.shape))
    res = identify(t, ref, meas)
    assert abs(res.p / p_true - 1) < 0.02
    assert res.rms_deg < 0.06
    assert res.joints == 3 and res.samples == 60

def test_delay_is_fitted_when_asked() -> None:
    t, ref = _steps()
    clean = response(32.22, 0.008, t, ref, ref[0])
    meas = _quantize(clean)
    plain = identify(t, ref, meas)
    with_delay = identify(t, ref, meas, fit_delay=True)
    assert abs(with_delay.p / 32.22 - 1) < 0.02
    assert with_delay.delay_s == pytest.approx(0.008, abs=0.002)
    assert with_delay.rms_deg < plain.rms_deg / 3  # ignoring the delay biases p and the fit
    assert abs(plain.p / 32.22 - 1) > 0.05

@pytest.mark.parametrize("clock_s", [0.0, 78_000.0])
def test_a_small_delay_is_fitted_on_a_clock_far_from_zero(clock_s: float) -> None:
    """A delay of a few ms (a goal written after the read, as the executor does), on a log
    whose clock reads ~1e5 s (perf_counter): the fit leaves the delay's bound of 0."""
    t, ref = _steps()
    meas = _quantize(response(32.22, 0.002, t, ref, ref[0]))
    res = identify(t + clock_s, ref, meas, fit_delay=True)
    assert res.delay_s == pytest.approx(0.002, abs=0.0005)
    assert abs(res.p / 32.22 - 1) < 0.01

def test_single_joint_step_and_irregular_times() -> None:
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.018, 0.022, 50))
    ref = np.where(np.arange(50) < 4, 135.0, 160.0)
    meas = _quantize(response(32.22, 0.0, t, ref[:, None], np.array([135.0]))[:, 0])
    res = identify(t, ref, meas)
    assert abs(res.p / 32.22 - 1) < 0.02

def test_bad_input_is_refused() -> None:
    t, ref = _steps(10)
    with pytest.raises(BadInputError, match="never moves"):
        identify(t, np.full((10, 3), 1.0), np.full((10, 3), 1.0))
    with pytest.raises(BadInputError, match="increasing"):
        identify(t[::-1], ref, ref)
    with pytest.raises(BadInputError, match="rows"):
        identify(t, ref[:5], ref)
    with pytest.raises(BadInputError, match="at least 5"):
        identify(t[:3], ref[:3], ref[:3])
    bad = ref.copy()
    bad[2, 1] = np.nan
    with pytest.raises(BadInputError, match="non-finite"):
        identify(t, ref, bad)

def _step_data() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t, ref = _steps()
    return t, ref, _quantize(response(32.22, 0.0, t, ref, ref[0]))

@pytest.mark.parametrize(("edit", "words"), [
    (lambda t, r, m: (t, np.where(np.arange(60)[:, None] == 10, 1e308, r), m),
     ("reference", "1e+308", "±3600")),
    (lambda t, r, m: (t, r, m - 4000.0), ("measured", "±3600")),
    (lambda t, r, m: (t * 1e300, r, m), ("sample times", "±1e+10 s")),
    (lambda t, r, m: (t + 1e308, r, m), ("sample times", "±1e+10 s")),
    (lambda t, r, m: (t * 1e-300, r, m), ("sample interval", "below 0.0001 s")),
    (lambda t, r, m: (t * 1e5, r, m), ("span", "more than 86400 s")),
    (lambda t, r, m: (np.where(np.arange(60) == 20, t[19], t), r, m),
     ("strictly increasing", "sample 21")),
    (lambda t, r, m: (t, np.full_like(r, 100.0), np.full_like(m, 100.0)), ("never moves",)),
    (lambda t, r, m: (t, r[0] + 0.01 * (np.arange(60) >= 5)[:, None], m),
     ("reference moves by 0.01°", "0.5°")),
    (lambda t, r, m: (t, r, np.full_like(m, 100.0)), ("measured position never moves",)),
])
def test_malformed_or_motionless_data_is_bad_input(edit, words) -> None:  # type: ignore[no-untyped-def]
    """Values beyond ±3600°, times that are not seconds of one record (beyond ±1e10 s,
    intervals under 0.1 ms, a span over a day, repeated), and data without a step of 0.5°
    in θ* and an answer in θ: refused (exit 4), never a traceback or a made-up p."""
    t, ref, meas = edit(*_step_data())
    with pytest.raises(BadInputError) as exc:
        identify(t, ref, meas)
    assert all(w in exc.value.message for w in words), exc.value.message

@pytest.mark.parametrize("fit_delay", [False, True])
def test_a_fit_that_does_not_determine_p_is_refused(fit_delay: bool) -> None:
    """A response faster than the samples (settled one sample after each step, p·Ts ≈ 100),
    an instant copy of the reference, no answer related to the reference (p on its lower
    bound), a delay beyond 0.25 s: SolverError (exit 7), not a made-up p."""
    t, ref = _steps()
    rng = np.random.default_rng(0)
    for meas, words in [
        (_quantize(response(5000.0, 0.0, t, ref, ref[0])), "cannot tell p"),
        (np.vstack([ref[:1], ref[:-1]]), "cannot tell p"),
        (ref[0] + rng.normal(0.0, 5.0, ref.shape), "search bound"),
    ]:
        with pytest.raises(SolverError, match=words):
            identify(t, ref, meas, fit_delay=fit_delay)
    if fit_delay:
        late = _quantize(response(32.22, 0.4, t, ref, ref[0]))
        with pytest.raises(SolverError, match="delay on its bound"):
            identify(t, ref, late, fit_delay=True)

def _bus_steps(agile) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:  # type: ignore[no-untyped-def]
    """One step-response record through the emulator: (t, refs, measured, the worst
    disturbance of the timing, s: a cycle's lateness or its read-and-write time)."""
    import time

    from spm_console.devices.base import CommError
    from spm_console.devices.dynamixel.bus import open_bus
    from spm_console.devices.emulator.bus import start_emulator

    with start_emulator(agile) as emu, open_bus(agile, emu.port) as bus:
        bus.set_torque(True)
        home = np.array(agile.home.theta_deg)
        step1, step2 = home + np.array([15.0, -10.0, 5.0]), home + np.array([-5.0, 8.0, -12.0])
        plan = [home] * 3 + [step1] * 30 + [step2] * 30
        ts, refs, meas = [], [], []
        worst = 0.0

        def read() -> np.ndarray:  # a reply a loaded machine read late: retried, a disturbance
            nonlocal worst
            for _attempt in range(3):
                try:
                    return bus.read_position_deg()
                except CommError:
                    worst = float("inf")  # the record is taken again (a lost sample: NaN)
            return np.full(3, np.nan)

        t_next = time.perf_counter()
        for ref in plan:
            while time.perf_counter() < t_next:
                time.sleep(0.0005)
            ts.append(time.perf_counter())
            meas.append(read())  # read, then send: the reference acts after t_k
            bus.write_goal_deg(ref)
            worst = max(worst, ts[-1] - t_next, time.perf_counter() - ts[-1])
            t_next += TS
            refs.append(ref)
    return np.array(ts), np.array(refs), np.array(meas), worst

