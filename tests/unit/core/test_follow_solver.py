"""Live following (receding-horizon MVN): optimal against cvxpy, warm = cold, safe, converging."""

from __future__ import annotations

import cvxpy as cp
import numpy as np
import pytest

from spm_console.core.planning.follow.result import FollowResult
from spm_console.core.planning.follow.solver import (
    TARGET_REFUSED,
    FollowSettings,
    FollowSolver,
    FollowWeights,
)
from spm_console.core.planning.follow.target import ProjectionError
from spm_console.core.planning.mvn import solve_mvn
from spm_console.core.polytope.region import Region
from spm_console.errors import BadInputError
from tests.support.planning_cases import MODEL

HOME = np.array([135.0, 135.0, 135.0])
VMAX = 50.0
LO, HI = np.full(3, 60.0), np.full(3, 160.0)
TIGHT = FollowSettings(tolerances=(1e-7,))


def _at(*offset_deg: float) -> np.ndarray:
    """HOME moved by the given offsets, deg."""
    return HOME + np.array(offset_deg)


def _region() -> Region:
    """Box 70..150° cut by two slanted planes 12° and 10° from HOME."""
    box = Region.box(70.0, 150.0)
    n = np.array([[1.0, 1.0, 1.0], [1.0, -1.0, 0.0]])
    n /= np.linalg.norm(n, axis=1)[:, None]
    return Region(np.vstack([box.A, n]), np.concatenate([box.b, n @ HOME + np.array([12.0, 10.0])]))


REGION = _region()


def _solver(**kw: object) -> FollowSolver:
    args: dict[str, object] = {"ref_lo_deg": LO, "ref_hi_deg": HI, "horizon": 50}
    args.update(kw)
    return FollowSolver(MODEL, REGION, VMAX, **args)  # type: ignore[arg-type]


def _cvxpy(solver: FollowSolver, th0: np.ndarray, om0: np.ndarray, target: np.ndarray) -> tuple[float, np.ndarray]:
    """The same QP written from the equations in cvxpy (tightened as the solver's QP is)."""
    H, w = solver.horizon, solver.weights
    norms = np.linalg.norm(REGION.A, axis=1)
    b = REGION.b - solver.margin_deg * norms
    v = VMAX - solver.speed_margin_degps
    th = cp.Variable((H + 1, 3))
    om = cp.Variable((H + 1, 3))
    ref = cp.Variable((H, 3))
    A, B = MODEL.A, MODEL.B
    cons = [th[0] == th0, om[0] == om0, om[H] == 0,
            th[1:] == A[0, 0] * th[:-1] + A[0, 1] * om[:-1] + B[0] * ref,
            om[1:] == A[1, 0] * th[:-1] + A[1, 1] * om[:-1] + B[1] * ref,
            cp.abs(om[1:]) <= v, th[1:] @ REGION.A.T <= np.tile(b, (H, 1)),
            ref >= np.tile(LO, (H, 1)), ref <= np.tile(HI, (H, 1)), th[H] >= LO, th[H] <= HI]
    cost = (cp.sum_squares(om[1:]) + w.track * cp.sum_squares(th[1:] - np.tile(target, (H, 1)))
            + w.terminal * cp.norm1(th[H] - target))
    prob = cp.Problem(cp.Minimize(cost), cons)
    # tight: references near the terminal state are sensitive (θ* = (θ(k+1) − …)/b₀, b₀ ≈ 0.14)
    prob.solve(solver="CLARABEL", tol_gap_abs=1e-10, tol_gap_rel=1e-10, tol_feas=1e-10)
    assert prob.status == "optimal"
    return float(prob.value), np.asarray(ref.value)


def _step(x: np.ndarray, u: np.ndarray) -> np.ndarray:
    """One period of the servo model for the three joints: x (3, 2) = [θ, θ̇]."""
    th = MODEL.A[0, 0] * x[:, 0] + MODEL.A[0, 1] * x[:, 1] + MODEL.B[0] * u
    om = MODEL.A[1, 0] * x[:, 0] + MODEL.A[1, 1] * x[:, 1] + MODEL.B[1] * u
    return np.stack([th, om], 1)


def _assert_safe(r: FollowResult, solver: FollowSolver) -> None:
    assert r.ok, r.reason
    assert float(REGION.violation_deg(r.position_deg[1:]).max()) <= 1e-9
    assert float(np.abs(r.velocity_degps[1:]).max()) <= VMAX + 1e-9
    assert np.all(r.reference_deg >= LO) and np.all(r.reference_deg <= HI)
    assert np.abs(r.velocity_degps[-1]).max() <= 0.1  # at rest at the horizon (to tolerance)


@pytest.mark.parametrize("target, state", [
    (_at(8.0, -6.0, 4.0), (HOME, np.zeros(3))),  # reachable: target as terminal state
    (_at(-40.0, 30.0, -35.0), (HOME, np.zeros(3))),  # beyond a face and too far for 1 s
    (_at(5.0, 5.0, 5.0), (_at(-3.0, -1.0, -2.0), np.array([30.0, -20.0, 10.0]))),  # moving
])
@pytest.mark.parametrize("backend", ["daqp", "osqp"])
def test_first_solve_matches_cvxpy(target: np.ndarray, state: tuple[np.ndarray, np.ndarray],
                                   backend: str) -> None:
    """Either backend (DAQP on the condensed QP, OSQP on the sparse one) gives cvxpy's optimum."""
    s = _solver(settings=FollowSettings(tolerances=(1e-7,), backend=backend))  # type: ignore[arg-type]
    r = s.solve(state[0], state[1], target)
    assert r.ok, r.reason
    assert r.detail.startswith(("daqp", "kept")) == (backend == "daqp")  # the backend asked answered
    if r.clamped:  # compare against the same (projected) target
        target = r.target_deg
    cost, ref = _cvxpy(s, state[0], state[1], target)
    assert r.cost == pytest.approx(cost, rel=1e-5)
    assert np.abs(r.reference_deg - ref).max() <= 1e-4
    _assert_safe(r, s)


def test_pure_mvn_terminal_equals_the_offline_planner() -> None:
    """With w = 0 and no tightening, a reachable target from rest gives the MVN plan (30)."""
    s = _solver(weights=FollowWeights(track=0.0, terminal=1e5), settings=TIGHT, margin_deg=0.0,
                speed_margin_degps=1e-9)
    goal = _at(5.0, -4.0, 3.0)
    r = s.solve(HOME, np.zeros(3), goal)
    assert r.status == "reached"
    plan = solve_mvn(MODEL, HOME, goal, 50, REGION, VMAX, hold_first=False, ref_lo_deg=LO, ref_hi_deg=HI)
    assert np.abs(r.reference_deg - plan.reference_deg[:-1]).max() <= 1e-3
    assert r.cost == pytest.approx(plan.cost, rel=1e-5)


@pytest.mark.parametrize("backend", ["daqp", "osqp"])
def test_warm_start_gives_the_cold_answers(backend: str) -> None:
    st = FollowSettings(tolerances=(1e-7,), backend=backend)  # type: ignore[arg-type]
    warm, cold = _solver(settings=st), _solver(settings=st)
    x = np.stack([HOME, np.zeros(3)], 1)
    for k in range(40):
        target = HOME + 8.0 * np.sin(np.pi * 0.02 * k) * np.array([1.0, -1.0, 0.5])
        rw = warm.solve(x[:, 0], x[:, 1], target)
        rc = cold.solve(x[:, 0], x[:, 1], target, warm=False)
        assert rw.warm == (k > 0) and not rc.warm
        assert np.abs(rw.reference_deg - rc.reference_deg).max() <= 1e-3
        assert rw.cost == pytest.approx(rc.cost, rel=1e-5)
        x = _step(x, rw.first_reference_deg)


def test_step_change_is_followed_at_once() -> None:
    s = _solver()
    a, b = _at(5.0, 5.0, -5.0), _at(-8.0, 4.0, 6.0)
    x = np.stack([HOME, np.zeros(3)], 1)
    prev: FollowResult | None = None
    for k in range(60):
        r = s.solve(x[:, 0], x[:, 1], a if k < 30 else b)
        _assert_safe(r, s)
        if k == 30:
            assert prev is not None
            assert np.abs(r.first_reference_deg - prev.reference_at(1)).max() > 1.0
            assert np.array_equal(r.target_deg, b) and not r.clamped
        prev = r
        x = _step(x, r.first_reference_deg)
    assert np.abs(x[:, 0] - b).max() <= 0.5  # well on the way after 0.6 s


def test_outside_target_is_projected_and_reported() -> None:
    s = _solver()
    far = _at(20.0, 20.0, 20.0)  # beyond the slanted face (12° from HOME) and the box
    r = s.solve(HOME, np.zeros(3), far)
    assert r.ok and r.clamped
    assert np.array_equal(r.requested_deg, far)
    assert float(REGION.violation_deg(r.target_deg)) == 0.0
    # the nearest point of the tightened region, by an independent QP
    p = cp.Variable(3)
    b = REGION.b - 2.0 * s.margin_deg * np.linalg.norm(REGION.A, axis=1)  # twice the QP margin
    cp.Problem(cp.Minimize(cp.sum_squares(p - far)), [REGION.A @ p <= b]).solve(solver="CLARABEL")
    assert np.abs(r.target_deg - p.value).max() <= 1e-5
    assert r.clamp_deg == pytest.approx(float(np.linalg.norm(far - p.value)), abs=1e-5)
    inside = s.solve(HOME, np.zeros(3), _at(1.0, 0.0, 0.0))
    assert not inside.clamped and inside.clamp_deg == 0.0
    # a preview with one sample outside is clamped too
    preview = np.tile(HOME, (50, 1))
    preview[10] = far
    assert s.solve(HOME, np.zeros(3), preview).clamped


def test_a_target_without_a_projection_is_refused_never_replaced_by_the_centre() -> None:
    """A target 1e12° away: OSQP finds no nearest point. The target is refused (the plan in
    use goes on); it used to be replaced by the region's Chebyshev centre, ~25° away."""
    absurd = np.array([1e12, -1e12, 3e11])
    with pytest.raises(ProjectionError, match="is refused"):
        _solver().project(absurd)
    s = _solver()
    r = s.solve(HOME, np.zeros(3), absurd)
    assert not r.ok and r.status == "failed" and r.detail == TARGET_REFUSED
    assert "is refused" in r.reason and not r.clamped
    assert r.reference_deg.shape == (0, 3)  # nothing to send
    assert np.array_equal(r.target_deg, HOME)  # no substitute target
    assert s.solve(HOME, np.zeros(3), _at(1.0, 0.0, 0.0)).ok  # the solver serves on


def test_only_the_nearest_point_passes_the_projection_certificate() -> None:
    """An answer the QP calls solved is kept only with a certificate of optimality: the
    nearest point (by an independent QP) passes it, the centre or a point beside it fails."""
    s = _solver()
    proj = s._projector
    far = _at(200.0, -150.0, 90.0)
    p = cp.Variable(3)
    cp.Problem(cp.Minimize(cp.sum_squares(p - far)), [proj.A @ p <= proj.b, p >= proj.lo,
                                                     p <= proj.hi]).solve(solver="CLARABEL")
    nearest, _ = proj.project(far)
    np.testing.assert_allclose(nearest, p.value, atol=1e-5)
    assert proj._nearest(nearest, far)
    assert not proj._nearest(proj.centre, far)
    beside = proj._pull_inside(nearest + np.array([0.0, 0.0, -2.0]))
    assert beside is not None and not proj._nearest(beside, far)


def test_predicted_samples_stay_inside_along_a_run() -> None:
    s = _solver()
    rng = np.random.default_rng(3)
    targets = [HOME + rng.uniform(-30.0, 20.0, 3) for _ in range(6)]
    x = np.stack([HOME, np.zeros(3)], 1)
    for k in range(150):
        r = s.solve(x[:, 0], x[:, 1], targets[k // 25])
        _assert_safe(r, s)
        x = _step(x, r.first_reference_deg)
        assert float(REGION.violation_deg(x[:, 0])) <= 1e-9


def test_start_outside_is_refused_with_a_reason() -> None:
    s = _solver()
    r = s.solve(_at(20.0, 0.0, 0.0), np.zeros(3), HOME)
    assert r.status == "infeasible" and not r.ok
    assert "outside the region" in r.reason
    assert r.reference_deg.shape == (0, 3)
    with pytest.raises(ValueError):
        r.first_reference_deg  # noqa: B018 - the property raises


def test_closed_loop_converges_and_stays_at_rest() -> None:
    s = _solver()
    goal = _at(-10.0, 6.0, 8.0)
    x = np.stack([HOME, np.zeros(3)], 1)
    statuses = []
    for _ in range(150):
        r = s.solve(x[:, 0], x[:, 1], goal)
        statuses.append(r.status)
        x = _step(x, r.first_reference_deg)
    assert np.abs(x[:, 0] - goal).max() <= 1e-3
    assert np.abs(x[:, 1]).max() <= 1e-3
    assert statuses[-1] == "reached"
    assert np.abs(r.reference_deg - goal).max() <= 1e-3  # holding: every reference at the goal


def test_reference_at_continues_the_plan_and_holds() -> None:
    s = _solver()
    r = s.solve(HOME, np.zeros(3), _at(4.0, 0.0, 0.0))
    assert np.array_equal(r.reference_at(0), r.first_reference_deg)
    assert np.array_equal(r.reference_at(7), r.reference_deg[7])
    assert np.array_equal(r.reference_at(500), r.position_deg[-1])


def test_skipped_periods_shift_the_warm_start() -> None:
    s, cold = _solver(settings=TIGHT), _solver(settings=TIGHT)
    goal = _at(6.0, -6.0, 2.0)
    r = s.solve(HOME, np.zeros(3), goal)
    x = np.stack([HOME, np.zeros(3)], 1)
    for j in range(3):  # three periods streamed from the same plan
        x = _step(x, r.reference_at(j))
    r2 = s.solve(x[:, 0], x[:, 1], goal, elapsed=3)
    rc = cold.solve(x[:, 0], x[:, 1], goal, warm=False)
    assert r2.warm and np.abs(r2.reference_deg - rc.reference_deg).max() <= 1e-3


@pytest.mark.parametrize("kw", [{"vmax_degps": 0.0}, {"horizon": 1}, {"ref_lo_deg": HI, "ref_hi_deg": LO}])
def test_bad_construction(kw: dict[str, object]) -> None:
    args: dict[str, object] = {"model": MODEL, "region": REGION, "vmax_degps": VMAX}
    args.update(kw)
    with pytest.raises(BadInputError):
        FollowSolver(**args)  # type: ignore[arg-type]


def test_bad_state_or_target_shape() -> None:
    s = _solver(horizon=10)
    with pytest.raises(BadInputError):
        s.solve(HOME, np.zeros(3), np.zeros((5, 3)))
    with pytest.raises(BadInputError):
        s.solve(HOME[:2], np.zeros(3), HOME)
    with pytest.raises(BadInputError):
        s.solve(HOME, np.array([0.0, np.nan, 0.0]), HOME)


def test_an_untimed_solve_ignores_the_time_limit_and_the_next_timed_one_keeps_it() -> None:
    """The follower's first solve, before torque-on, runs without the loop's budget (a cold
    solve in a fresh region may need more); the budget holds again for the next solve."""
    s = _solver(settings=FollowSettings(time_limit_s=1e-9))
    target = _at(5.0, 5.0, -5.0)
    assert not s.solve(HOME, np.zeros(3), target, warm=False).ok  # out of time
    first = s.solve(HOME, np.zeros(3), target, warm=False, timed=False)
    assert first.ok, first.reason
    _assert_safe(first, s)
    again = s.solve(HOME, np.zeros(3), target, warm=False)
    assert not again.ok and "out of time" in again.reason


def test_a_daqp_solve_out_of_time_fails_without_setting_osqp_up() -> None:
    """When DAQP's time is up there is none left for OSQP: the solve fails as out of time
    and the sparse QP is never assembled (setting OSQP up would only make the answer later)."""
    s = _solver(settings=FollowSettings(time_limit_s=1e-9, backend="daqp"))
    res = s.solve(HOME, np.zeros(3), _at(5.0, 5.0, -5.0), warm=False)
    assert not res.ok and res.reason.startswith("out of time"), res.reason
    assert s._mats_built is None and s._osqp_solver is None


def test_the_linear_range_and_the_step_from_the_reference_in_use_hold_as_in_cvxpy() -> None:
    """An identified servo (ζ = 0.8) with a 2° linear range, the reference in use 6° off the
    state: the first reference steps at most 10° from it, every reference leads the position by
    at most 2° (both less the solver's margin over its tolerance), and the optimum equals the
    cvxpy formulation with the same rows."""
    from spm_console.core.planning.follow.solver import RULE_MARGIN_DEG
    from spm_console.core.servo.model import Dynamics, discretize

    model = discretize(Dynamics(43.0, 0.8), MODEL.ts)
    solver = FollowSolver(model, REGION, VMAX, ref_lo_deg=LO, ref_hi_deg=HI, horizon=40,
                          settings=TIGHT, lead_max_deg=2.0)
    th0, om0, prev = HOME, np.zeros(3), HOME + np.array([-6.0, 6.0, 0.0])
    target = _at(6.0, -3.0, 3.0)  # inside the region: the solver does not move it
    r = solver.solve(th0, om0, target, warm=False, timed=False, previous_reference_deg=prev)
    assert r.ok, r.reason
    steps = np.abs(np.diff(np.vstack([prev, r.reference_deg]), axis=0))
    assert steps.max() <= 10.0 + 1e-6
    lead = np.abs(r.reference_deg - r.position_deg[:-1])
    assert lead.max() <= 2.0 - RULE_MARGIN_DEG + 1e-5 and lead.max() > 1.9  # it binds
    step = 10.0 - 1e-6 - RULE_MARGIN_DEG  # the runtime's bounds less the solver's margin
    H, w = solver.horizon, solver.weights
    b = REGION.b - solver.margin_deg * np.linalg.norm(REGION.A, axis=1)
    th, om, ref = cp.Variable((H + 1, 3)), cp.Variable((H + 1, 3)), cp.Variable((H, 3))
    A, B = model.A, model.B
    cons = [th[0] == th0, om[0] == om0, om[H] == 0,
            th[1:] == A[0, 0] * th[:-1] + A[0, 1] * om[:-1] + B[0] * ref,
            om[1:] == A[1, 0] * th[:-1] + A[1, 1] * om[:-1] + B[1] * ref,
            cp.abs(om[1:]) <= VMAX - solver.speed_margin_degps,
            th[1:] @ REGION.A.T <= np.tile(b, (H, 1)),
            ref >= np.tile(LO, (H, 1)), ref <= np.tile(HI, (H, 1)), th[H] >= LO, th[H] <= HI,
            cp.abs(ref[0] - prev) <= step, cp.abs(ref[1:] - ref[:-1]) <= step,
            cp.abs(ref - th[:-1]) <= 2.0 - RULE_MARGIN_DEG]
    cost = (cp.sum_squares(om[1:]) + w.track * cp.sum_squares(th[1:] - np.tile(target, (H, 1)))
            + w.terminal * cp.norm1(th[H] - target))
    prob = cp.Problem(cp.Minimize(cost), cons)
    prob.solve(solver="CLARABEL", tol_gap_abs=1e-10, tol_gap_rel=1e-10, tol_feas=1e-10)
    assert prob.status == "optimal"
    assert r.cost == pytest.approx(float(prob.value), rel=1e-5)
