"""An identified servo's model: ωn, ζ and a transport delay, against independent references
(python-control's c2d, scipy's matrix exponential, a fine brute-force simulation)."""

from __future__ import annotations

import control
import numpy as np
import pytest
from scipy.linalg import expm

from spm_console.core.servo.estimation import ModelPredictor
from spm_console.core.servo.model import Dynamics, discretize, exact_step, simulate_continuous

ZETAS = [0.25, 0.79, 1.0 - 1e-9, 1.0, 1.0 + 1e-9, 1.5, 4.0]


def _ss(wn: float, z: float) -> tuple[np.ndarray, np.ndarray]:
    """ẍ = ωn²(u − x) − 2ζωn ẋ, written out here rather than taken from the package."""
    return np.array([[0.0, 1.0], [-wn * wn, -2.0 * z * wn]]), np.array([[0.0], [wn * wn]])


@pytest.mark.parametrize("zeta", ZETAS)
@pytest.mark.parametrize(("wn", "ts"), [(32.22, 0.02), (44.3, 0.02), (5.0, 0.001), (300.0, 0.05)])
def test_exact_sampling_matches_python_control(wn: float, zeta: float, ts: float) -> None:
    A, B = _ss(wn, zeta)
    sd = control.c2d(control.ss(A, B, [[1.0, 0.0]], [[0.0]]), ts, method="zoh")
    m = discretize(Dynamics(wn, zeta), ts)
    np.testing.assert_allclose(m.A, np.asarray(sd.A), rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(m.B, np.asarray(sd.B).reshape(2), rtol=1e-9, atol=1e-11)
    tus = discretize(Dynamics(wn, zeta), ts, "tustin")
    sb = control.c2d(control.ss(A, B, [[1.0, 0.0]], [[0.0]]), ts, method="bilinear")
    np.testing.assert_allclose(tus.A, np.asarray(sb.A), rtol=1e-9, atol=1e-11)


def test_a_bare_p_is_the_papers_double_pole() -> None:
    p, tau = 32.22, 0.013
    e = np.exp(-p * tau)
    Phi, Gam = exact_step(p, tau)
    np.testing.assert_allclose(Phi, e * np.array([[1 + p * tau, tau], [-p * p * tau, 1 - p * tau]]),
                               rtol=1e-13)
    np.testing.assert_allclose(Gam, [1 - e * (1 + p * tau), p * p * tau * e], rtol=1e-12)
    assert discretize(p, 0.02).dynamics == Dynamics(p)


@pytest.mark.parametrize("zeta", [0.3, 0.79, 1.0, 1.3, 2.0, 5.0])
def test_step_figures_match_a_fine_simulation(zeta: float) -> None:
    """Peak speed, overshoot and the slowest decay rate against a 1e-5 s matrix-exponential
    march and the eigenvalues of Ac."""
    wn = 40.0
    A, B = _ss(wn, zeta)
    h = 1e-5
    M = expm(np.block([[A, B], [np.zeros((1, 3))]]) * h)
    x = np.zeros(2)
    pos, vel = [], []
    for _ in range(int(12.0 / (zeta * wn if zeta <= 1 else wn * (zeta - np.sqrt(zeta**2 - 1))) / h)):
        x = M[:2, :2] @ x + M[:2, 2]
        pos.append(x[0])
        vel.append(x[1])
    d = Dynamics(wn, zeta)
    assert d.step_peak_speed() == pytest.approx(max(vel), rel=1e-4)
    assert d.overshoot() == pytest.approx(max(0.0, max(pos) - 1.0), abs=1e-6)
    assert d.slowest_rate == pytest.approx(min(-np.linalg.eigvals(A).real), rel=1e-9)


def test_the_predictor_applies_the_delay_exactly() -> None:
    """References sent every Ts (and at irregular instants) act d later: against a 0.1 ms
    brute-force march of the continuous model under the shifted staircase."""
    d = Dynamics(44.3, 0.79, 0.0047)
    ts = 0.02
    m = discretize(d, ts)
    rng = np.random.default_rng(3)
    refs = 100.0 + np.cumsum(rng.uniform(-3, 3, (40, 3)), axis=0)
    pred = ModelPredictor(m, refs[0])
    got = []
    for r in refs:
        got.append(pred.position_deg)
        pred.advance(r)
    A, B = _ss(d.wn, d.zeta)
    h = 1e-4
    M = expm(np.block([[A, B], [np.zeros((1, 3))]]) * h)
    x = np.vstack([refs[0], np.zeros(3)])
    want = []
    for k in range(len(refs)):
        want.append(x[0].copy())
        for j in range(round(ts / h)):
            t = k * ts + j * h
            idx = int(np.floor((t - d.delay_s) / ts + 1e-9))
            u = refs[0] if idx < 0 else refs[idx]
            x = M[:2, :2] @ x + np.outer(M[:2, 2], u)
    np.testing.assert_allclose(np.array(got), np.array(want), atol=1e-9)
    # the same references through propagate() with each period cut in two uneven spans
    again = ModelPredictor(m, refs[0])
    for k, r in enumerate(refs[:-1]):
        np.testing.assert_allclose(again.position_deg, want[k], atol=1e-9)
        again.propagate([(0.007, r), (0.013, r)])


def test_without_delay_the_samples_are_the_continuous_response() -> None:
    d = Dynamics(44.3, 0.6)
    rng = np.random.default_rng(4)
    ref = np.cumsum(rng.uniform(-2, 2, (30, 3)), axis=0)
    x0 = np.column_stack([ref[0], np.zeros(3)])
    _, xs = simulate_continuous(d, 0.02, x0, ref, 5)
    pred = ModelPredictor(discretize(d, 0.02), ref[0])
    for k in range(len(ref) - 1):
        np.testing.assert_allclose(pred.position_deg, xs[5 * k, :, 0], atol=1e-9)
        pred.advance(ref[k])
