"""Servo model (27)-(28): ZOH and Tustin discretization, eq. (35), exact sub-steps, simulation."""

from __future__ import annotations

import control
import numpy as np
import pytest
from scipy.linalg import expm

from spm_console.core.servo.model import (
    continuous,
    discretize,
    exact_step,
    simulate,
    simulate_continuous,
    substeps,
)

P, TS = 32.22, 0.02
#: The paper's printed eq. (35).
A35 = np.array([[0.5481, 0.0435], [-45.1937, 3.3534]])
B35 = np.array([0.4519, 45.1937])


def test_zoh_matches_spec_values() -> None:
    m = discretize(P, TS, "zoh")
    np.testing.assert_allclose(m.A, [[0.8633, 0.0105], [-10.900, 0.1867]], atol=5e-4)
    np.testing.assert_allclose(m.B, [0.1367, 10.900], atol=5e-4)
    # independent: the matrix exponential of the augmented system
    Ac, Bc = continuous(P)
    E = expm(np.block([[Ac, Bc], [np.zeros((1, 3))]]) * TS)
    np.testing.assert_allclose(m.A, E[:2, :2], atol=1e-12)
    np.testing.assert_allclose(m.B, E[:2, 2], atol=1e-12)
    assert np.abs(np.linalg.eigvals(m.A)) == pytest.approx([np.exp(-P * TS)] * 2, rel=1e-5)


def test_paper_eq35_is_tustin_of_the_unstable_plus_p_system() -> None:
    eig = np.sort(np.linalg.eigvals(A35).real)
    assert eig == pytest.approx([1.912, 1.989], abs=2e-3)  # unstable: outside the unit circle
    # Tustin of (27) with the poles at +p reproduces the printed numbers ...
    Ac, Bc = continuous(-P)
    sd = control.c2d(control.ss(Ac, Bc, [[1.0, 0.0]], [[0.0]]), TS, method="bilinear")
    assert np.asarray(sd.A) == pytest.approx(A35, abs=1e-4)
    assert np.asarray(sd.B).ravel() == pytest.approx(B35, abs=1e-4)
    # ... and what our code produces (−p, either method) is different and stable
    for method in ("zoh", "tustin"):
        m = discretize(P, TS, method)  # type: ignore[arg-type]
        assert np.max(np.abs(np.linalg.eigvals(m.A))) < 1.0
        assert np.abs(m.A - A35).max() > 0.3


def test_tustin_option() -> None:
    m = discretize(P, TS, "tustin")
    a = P * TS / 2
    # bilinear map of the double pole −p: z = (1 − pTs/2) / (1 + pTs/2), twice
    assert np.linalg.eigvals(m.A).real == pytest.approx([(1 - a) / (1 + a)] * 2, abs=1e-6)
    assert m.method == "tustin" and m.to_dict()["discretization"] == "tustin"


def test_exact_step_and_substeps_compose() -> None:
    Ac, Bc = continuous(P)
    for tau in (0.001, 0.0073, TS):
        Phi, Gam = exact_step(P, tau)
        E = expm(np.block([[Ac, Bc], [np.zeros((1, 3))]]) * tau)
        assert Phi == pytest.approx(E[:2, :2], abs=1e-12)
        assert Gam == pytest.approx(E[:2, 2], abs=1e-12)
    Phis, Gams = substeps(P, TS, 5)
    assert Phis.shape == (4, 2, 2) and Gams.shape == (4, 2)
    # two sub-steps of 2Ts/5 and 3Ts/5 make one full step
    Pa, Ga = Phis[1], Gams[1]
    Pb, Gb = exact_step(P, 3 * TS / 5)
    m = discretize(P, TS)
    assert Pb @ Pa == pytest.approx(m.A, abs=1e-12)
    assert Pb @ Ga + Gb == pytest.approx(m.B, abs=1e-12)
    assert substeps(P, TS, 1)[0].shape == (0, 2, 2)
    with pytest.raises(ValueError):
        substeps(P, TS, 0)


def test_simulation_matches_python_control() -> None:
    rng = np.random.default_rng(3)
    ref = 100 + 10 * rng.standard_normal((40, 3))
    m = discretize(P, TS)
    x0 = np.column_stack([[100.0, 90.0, 80.0], [0.0, 5.0, -3.0]])
    xs = simulate(m, x0, ref)
    sysd = control.ss(m.A, m.B.reshape(2, 1), np.eye(2), np.zeros((2, 1)), TS)
    for i in range(3):
        r = control.forced_response(sysd, T=np.arange(40) * TS, U=ref[:, i], X0=x0[i])
        assert xs[:, i, :] == pytest.approx(np.asarray(r.outputs).T, abs=1e-9)
    # the continuous simulation passes through the samples and is smooth in between
    t, xc = simulate_continuous(P, TS, x0, ref, 10)
    assert t.shape == (39 * 10 + 1,)
    assert xc[::10] == pytest.approx(xs, abs=1e-9)


@pytest.mark.parametrize("method", ["zoh", "tustin"])
@pytest.mark.parametrize(("p", "ts"), [(32.22, 0.02), (5.0, 0.001), (80.0, 0.05), (500.0, 0.02)])
def test_closed_form_matches_python_control(method: str, p: float, ts: float) -> None:
    """The core's closed forms against python-control's c2d (an independent implementation)."""
    Ac, Bc = continuous(p)
    sd = control.c2d(control.ss(Ac, Bc, [[1.0, 0.0]], [[0.0]]), ts,
                     method="bilinear" if method == "tustin" else "zoh")
    m = discretize(p, ts, method)  # type: ignore[arg-type]
    np.testing.assert_allclose(m.A, np.asarray(sd.A), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(m.B, np.asarray(sd.B).reshape(2), rtol=1e-10, atol=1e-12)
