"""The follow QP condensed for DAQP: its impulse responses are the model's, its answers the
sparse QP's (OSQP), and where DAQP gives no answer OSQP decides."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.core.planning.follow import daqp_follow, dense
from spm_console.core.planning.follow.daqp_follow import DenseAnswer
from spm_console.core.planning.follow.dense import dense_entries, impulse
from spm_console.core.planning.follow.osqp_follow import FollowSettings
from spm_console.core.planning.follow.qp import predict
from spm_console.core.planning.follow.solver import FollowSolver
from spm_console.core.polytope.region import Region
from spm_console.core.servo.model import Dynamics, discretize
from tests.support.planning_cases import MODEL

HOME = np.array([135.0, 135.0, 135.0])
LO, HI = np.full(3, 60.0), np.full(3, 160.0)
REGION = Region.box(110.0, 150.0)


@pytest.mark.parametrize("model", [MODEL, discretize(Dynamics(43.0, 0.8), MODEL.ts)])
def test_impulse_responses_are_the_model_recursion(model: object) -> None:
    """θ(k) = f_θ(k)·x(0) + Σ T_θ[k, j] θ*(j): the same numbers as stepping (28) forward."""
    rng = np.random.default_rng(3)
    H = 30
    Tth, Tom, fth, fom = impulse(model, H)  # type: ignore[arg-type]
    th0, om0 = rng.uniform(100, 150, 3), rng.uniform(-40, 40, 3)
    ref = rng.uniform(100, 150, (H, 3))
    th, om = predict(model, th0, om0, ref)  # type: ignore[arg-type]
    x = np.stack([th0, om0])
    assert np.abs(fth @ x + Tth @ ref - th[1:]).max() <= 1e-9
    assert np.abs(fom @ x + Tom @ ref - om[1:]).max() <= 1e-7
    assert np.all(np.triu(Tth, 1) == 0.0) and np.all(np.triu(Tom, 1) == 0.0)  # causal
    # the solver's prediction of a DAQP answer is this form, samples 0..H
    d = dense.build_dense(model, REGION, 50.0, H, LO, HI, 1.0, 0.0, 0.0)  # type: ignore[arg-type]
    rth, rom = d.response(th0, om0, ref)
    assert rth.shape == th.shape and rom.shape == om.shape
    assert np.abs(rth - th).max() <= 1e-9 and np.abs(rom - om).max() <= 1e-7


def _run(backend: str, steps: int = 60, lead: float | None = 2.0) -> tuple[np.ndarray, list[str]]:
    """A closed loop on the model toward a moving target: the first references and details."""
    s = FollowSolver(MODEL, REGION, 50.0, 40, LO, HI, lead_max_deg=lead,
                     settings=FollowSettings(tolerances=(1e-8,), backend=backend))  # type: ignore[arg-type]
    th, om, prev = HOME.copy(), np.zeros(3), None
    refs, details = [], []
    for k in range(steps):  # a target that leaves the region (a face at 150°) now and then
        target = HOME + 20.0 * np.sin(0.1 * k) * np.array([1.0, -0.5, 0.8])
        r = s.solve(th, om, target, previous_reference_deg=prev)
        assert r.ok, r.reason
        u = r.first_reference_deg
        th, om = (MODEL.A[0, 0] * th + MODEL.A[0, 1] * om + MODEL.B[0] * u,
                  MODEL.A[1, 0] * th + MODEL.A[1, 1] * om + MODEL.B[1] * u)
        prev = u
        refs.append(u)
        details.append(r.detail)
    return np.array(refs), details


def test_daqp_follows_as_osqp_does() -> None:
    """The same closed loop, both backends: the same references (OSQP at a tight tolerance,
    DAQP exact on its active set), every solve of the dense backend answered by DAQP or by
    the previous active set certified again."""
    rd, dd = _run("daqp")
    ro, do = _run("osqp")
    assert all(d == "daqp: optimal" or d.startswith("kept: optimal") for d in dd), dd
    assert not any(d.startswith(("daqp", "kept")) for d in do)
    assert np.abs(rd - ro).max() <= 1e-5


def test_osqp_decides_when_daqp_gives_no_answer(monkeypatch: pytest.MonkeyPatch) -> None:
    """DAQP out of iterations: OSQP answers that period, and the answer is the same optimum."""
    s = FollowSolver(MODEL, REGION, 50.0, 40, LO, HI)
    target = HOME + np.array([8.0, -6.0, 4.0])
    good = s.solve(HOME, np.zeros(3), target, warm=False)
    monkeypatch.setattr(daqp_follow.DaqpFollow, "solve",
                        lambda *a, **k: DenseAnswer(-4, np.zeros((0, 3)), 10000))
    r = s.solve(HOME, np.zeros(3), target, warm=False)
    assert r.ok and not r.detail.startswith("daqp")
    assert np.abs(r.reference_deg - good.reference_deg).max() <= 1e-4


def test_an_infeasible_state_is_refused_by_both() -> None:
    """At the face, moving out of it faster than the servo can stop: infeasible either way."""
    for backend in ("daqp", "osqp"):
        s = FollowSolver(MODEL, REGION, 50.0, 40, LO, HI,
                         settings=FollowSettings(backend=backend))  # type: ignore[arg-type]
        r = s.solve(np.array([149.9, 135.0, 135.0]), np.array([400.0, 0.0, 0.0]), HOME)
        assert r.status == "infeasible" and not r.ok, (backend, r.status, r.reason)


def test_a_long_horizon_goes_to_osqp() -> None:
    """A condensed QP above the size budget is not built: OSQP solves it."""
    assert dense_entries(50, 28) <= dense.DENSE_MAX_ENTRIES < dense_entries(400, 6)
    s = FollowSolver(MODEL, REGION, 50.0, 400, LO, HI)
    r = s.solve(HOME, np.zeros(3), HOME + np.array([5.0, -5.0, 5.0]))
    assert r.ok and not r.detail.startswith("daqp")
