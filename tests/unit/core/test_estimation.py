"""Kalman velocity estimation against an independent continuous-time simulation of (27)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from spm_console.core.servo.estimation import (
    FiniteDifference,
    KalmanVelocity,
    ModelPredictor,
    process_noise,
)
from spm_console.core.servo.model import discretize

P, TS = 32.22, 0.02
TICK = 360.0 / 4096


def _min_jerk(a: float, b: float, n_move: int, n_total: int) -> np.ndarray:
    s = np.minimum(np.arange(n_total) / n_move, 1.0)
    return a + (b - a) * (10 * s**3 - 15 * s**4 + 6 * s**5)


def _truth(ref: np.ndarray, delay_s: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities of (27) at k·Ts by solve_ivp (RK45, tight tolerances).

    The reference θ*(k) takes effect ``delay_s`` after k·Ts (a bus that is not instantaneous).
    """

    def rhs(_t: float, x: np.ndarray, u: float) -> list[float]:
        return [x[1], P * P * (u - x[0]) - 2 * P * x[1]]

    x = np.array([ref[0], 0.0])
    pos, vel = [x[0]], [x[1]]
    for k in range(len(ref) - 1):
        prev = ref[k - 1] if k > 0 else ref[0]
        for u, span in ((prev, delay_s), (ref[k], TS - delay_s)):
            if span > 0:
                x = solve_ivp(rhs, (0, span), x, args=(u,), rtol=1e-10, atol=1e-10).y[:, -1]
        pos.append(x[0])
        vel.append(x[1])
    return np.array(pos), np.array(vel)


def _estimate(ref: np.ndarray, z: list[np.ndarray | None]) -> tuple[np.ndarray, np.ndarray]:
    model = discretize(P, TS)
    kf = KalmanVelocity(model, np.full(3, z[0][0]), 0.05, 0.02)  # type: ignore[index]
    fd = FiniteDifference(TS)
    fd.step(z[0])
    kv, fv = [np.zeros(3)], [np.zeros(3)]
    for k in range(1, len(ref)):
        _, v = kf.step(np.full(3, ref[k - 1]), z[k])
        kv.append(v)
        fv.append(fd.step(z[k]).copy())
    return np.array(kv)[:, 0], np.array(fv)[:, 0]


@pytest.mark.parametrize("delay_s", [0.0, 0.002])
def test_kalman_beats_finite_differences_on_quantized_positions(delay_s: float) -> None:
    ref = _min_jerk(127.5, 66.8, 100, 151)
    pos, vel = _truth(ref, delay_s)
    z = [np.full(3, np.round(p / TICK) * TICK) for p in pos]  # 4096-tick encoder
    kv, fv = _estimate(ref, z)
    rms_kf = float(np.sqrt(np.mean((kv - vel) ** 2)))
    rms_fd = float(np.sqrt(np.mean((fv - vel) ** 2)))
    assert rms_kf <= 1.0, rms_kf
    assert rms_kf <= 0.5 * rms_fd, (rms_kf, rms_fd)
    assert float(np.abs(vel).max()) > 40.0  # a real motion, not a trivial one


def test_kalman_rides_through_missing_measurements() -> None:
    ref = _min_jerk(90.0, 130.0, 60, 91)
    pos, vel = _truth(ref)
    z: list[np.ndarray | None] = [np.full(3, np.round(p / TICK) * TICK) for p in pos]
    for k in (20, 21, 22, 50):  # failed bus reads: prediction only
        z[k] = None
    kv, _ = _estimate(ref, z)
    assert np.sqrt(np.mean((kv - vel) ** 2)) <= 1.0
    assert abs(kv[22] - vel[22]) < 2.0  # the model carries it through the gap


def test_model_predictor_matches_continuous_model() -> None:
    ref = _min_jerk(100.0, 140.0, 50, 80)
    pos, vel = _truth(ref)
    pred = ModelPredictor(discretize(P, TS), np.full(3, ref[0]))
    for k in range(len(ref)):
        assert pred.position_deg[0] == pytest.approx(pos[k], abs=1e-6)
        assert pred.velocity_degps[1] == pytest.approx(vel[k], abs=1e-5)
        pred.advance(np.full(3, ref[k]))


def test_finite_difference_spans_a_gap() -> None:
    fd = FiniteDifference(0.02)
    fd.step(np.array([0.0, 0.0, 0.0]))
    assert np.allclose(fd.step(None), 0.0)
    v = fd.step(np.array([0.4, 0.0, -0.4]))
    assert np.allclose(v, [10.0, 0.0, -10.0])  # 0.4 deg over two intervals


def test_process_noise_shape() -> None:
    Q = process_noise(0.02, 0.02)
    assert Q.shape == (2, 2)
    assert Q[0, 0] == pytest.approx(4e-4)
    assert Q[1, 1] == pytest.approx(1.0)
    assert Q[0, 1] == 0.0


def test_actual_write_and_read_instants_are_modelled() -> None:
    """A late cycle writes θ*(k) late and reads later still (a retry after a timeout):
    the timed filter propagates (27) over the actual spans and beats the filter that
    assumes the ideal grid, both judged at the read instants against the truth."""

    def rhs(_t: float, x: np.ndarray, u: float) -> list[float]:
        return [x[1], P * P * (u - x[0]) - 2 * P * x[1]]

    def go(x: np.ndarray, dt: float, u: float) -> np.ndarray:
        return solve_ivp(rhs, (0, dt), x, args=(u,), rtol=1e-10, atol=1e-10).y[:, -1]

    ref = _min_jerk(127.5, 66.8, 80, 111)
    n = len(ref)
    write = np.arange(n) * TS + 0.0002
    write[::9] += 0.012  # late cycles
    read = write + np.where(np.arange(n) % 7 == 3, 0.0045, 0.0006)
    x = np.array([ref[0], 0.0])
    t, u = 0.0, ref[0]
    z, truth_v = [], []
    for k in range(n):  # the truth: piecewise-constant references switched at the writes
        x, t, u = go(x, write[k] - t, u), write[k], ref[k]
        x, t = go(x, read[k] - t, u), read[k]
        z.append(np.full(3, np.round(x[0] / TICK) * TICK))
        truth_v.append(x[1])
    model = discretize(P, TS)
    timed = KalmanVelocity(model, z[0], 0.05, 0.02)
    ideal = KalmanVelocity(model, z[0], 0.05, 0.02)
    vt, vi = [], []
    t_state, u_prev = 0.0, ref[0]
    for k in range(n):
        spans = [(write[k] - t_state, np.full(3, u_prev)), (read[k] - write[k], np.full(3, ref[k]))]
        t_state, u_prev = read[k], ref[k]
        vt.append(timed.step_timed(spans, z[k])[1][0])
        vi.append(ideal.step(np.full(3, ref[k - 1] if k else ref[0]), z[k])[1][0] if k else 0.0)
    rms_t = float(np.sqrt(np.mean((np.array(vt) - truth_v) ** 2)))
    rms_i = float(np.sqrt(np.mean((np.array(vi) - truth_v) ** 2)))
    assert rms_t <= 0.3, (rms_t, rms_i)
    assert rms_t < 0.5 * rms_i, (rms_t, rms_i)
    fd = FiniteDifference(TS)
    fdv = [fd.step(z[k], float(read[k]))[0] for k in range(n)]
    assert rms_t < 0.5 * float(np.sqrt(np.mean((np.array(fdv) - truth_v) ** 2)))


def test_the_stacked_filter_is_three_independent_joint_filters() -> None:
    """The one filter on the three joints' stacked states gives what three filterpy filters,
    one per joint, give (the reference): exact timing with spans, a lost read, noise."""
    from filterpy.kalman import KalmanFilter

    from spm_console.core.servo.model import exact_step

    model = discretize(P, TS)
    rng = np.random.default_rng(3)
    theta0 = np.array([80.0, 110.0, 135.0])
    sigma_m, sigma_q = 0.05, 0.02
    stacked = KalmanVelocity(model, theta0, sigma_m, sigma_q, velocity0_std_degps=2.0)
    joints = []
    for i in range(3):
        kf = KalmanFilter(dim_x=2, dim_z=1, dim_u=1)
        kf.F, kf.B = model.A.copy(), model.B.reshape(2, 1).copy()
        kf.H, kf.R = np.array([[1.0, 0.0]]), np.array([[sigma_m**2]])
        kf.Q = process_noise(TS, sigma_q)
        kf.x = np.array([[theta0[i]], [0.0]])
        kf.P = np.diag([sigma_m**2, 2.0**2])
        joints.append(kf)
    ref = theta0.copy()
    for k in range(120):
        new_ref = ref + rng.normal(0.0, 0.8, 3)
        spans = [(0.001 + 0.004 * rng.random(), ref), (0.018 + 0.003 * rng.random(), new_ref)]
        z = None if k % 17 == 5 else ref + rng.normal(0.0, 0.3, 3)
        got = stacked.step_timed(spans, z)
        for i, kf in enumerate(joints):
            for dt, u in spans:
                Phi, Gam = exact_step(model.dynamics, dt)
                kf.predict(u=u[i], B=Gam.reshape(2, 1), F=Phi, Q=process_noise(TS, sigma_q) * (dt / TS))
            if z is not None:
                kf.update(z[i])
        want = (np.array([kf.x[0, 0] for kf in joints]), np.array([kf.x[1, 0] for kf in joints]))
        np.testing.assert_allclose(got[0], want[0], rtol=0, atol=1e-9)
        np.testing.assert_allclose(got[1], want[1], rtol=0, atol=1e-7)
        ref = new_ref
    # the ideal step too
    for _ in range(30):
        z = ref + rng.normal(0.0, 0.3, 3)
        got = stacked.step(ref, z)
        for i, kf in enumerate(joints):
            kf.predict(u=ref[i])
            kf.update(z[i])
        np.testing.assert_allclose(got[1], [kf.x[1, 0] for kf in joints], rtol=0, atol=1e-7)
