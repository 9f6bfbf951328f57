"""The follow QP's optimum from the previous active set (``follow/kept.py``): certified by
the KKT conditions, it is the optimum a one-shot DAQP solve of the same QP finds; where the
active set changed it claims nothing and DAQP answers."""

from __future__ import annotations

import daqp
import numpy as np

from spm_console.core.planning.follow import dense
from spm_console.core.planning.follow.daqp_follow import DAQP_OPTIMAL
from spm_console.core.planning.follow.kept import KeptActiveSet
from spm_console.core.planning.follow.osqp_follow import FollowSettings
from spm_console.core.planning.follow.solver import FollowSolver
from spm_console.core.polytope.region import Region
from tests.support.planning_cases import MODEL

HOME = np.array([135.0, 135.0, 135.0])
LO, HI = np.full(3, 60.0), np.full(3, 160.0)
REGION = Region.box(110.0, 150.0)
H = 40


def _one_shot(d: dense.DenseFollow, f: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The same QP by a fresh DAQP call (no workspace, no warm start): (H, 3) references."""
    x, _, flag, _ = daqp.solve(d.H_cost, f, d.A, hi, lo, d.sense.copy())
    assert flag == DAQP_OPTIMAL
    return np.asarray(x)[: 3 * d.H].reshape(d.H, 3)


def test_the_rows_through_the_responses_are_the_matrix_rows() -> None:
    """``DenseFollow.rows_of`` (what the certificate evaluates) equals A z, with and without
    the step and lead rows."""
    rng = np.random.default_rng(4)
    for step, lead in ((np.inf, np.inf), (10.0, np.inf), (10.0, 2.0)):
        d = dense.build_dense(MODEL, REGION, 50.0, H, LO, HI, 1.0, 0.05, 0.25, step, lead)
        z = rng.normal(size=d.n) * 10.0
        assert np.abs(d.rows_of(z) - d.A @ z).max() <= 1e-9


def test_kept_answers_are_the_one_shot_optimum_and_a_changed_set_goes_to_daqp() -> None:
    """A closed loop toward a target that leaves the region now and then (a face at 150°
    becomes active and inactive again): every answer, kept or solved, equals a fresh DAQP
    solve of the same QP, and both kinds occur."""
    s = FollowSolver(MODEL, REGION, 50.0, H, LO, HI, settings=FollowSettings(backend="daqp"))
    assert s._daqp is not None
    d = s._daqp.dense
    th, om, prev = HOME.copy(), np.zeros(3), None
    kinds: list[str] = []
    for k in range(80):
        target = HOME + 20.0 * np.sin(0.1 * k) * np.array([1.0, -0.5, 0.8])
        r = s.solve(th, om, target, previous_reference_deg=prev)
        assert r.ok, r.reason
        kinds.append(r.detail.split(":")[0])
        # the QP this period posed, solved again from nothing
        p = th if prev is None else prev
        ft, fo = d.free(th, om)
        tg = np.broadcast_to(r.target_deg, (H, 3))
        f = d.cost(ft, fo, tg, s.weights.terminal)
        lo, hi = d.bounds(th, om, r.target_deg, p, ft, fo)
        assert np.abs(r.reference_deg - _one_shot(d, f, lo, hi)).max() <= 1e-6, (k, kinds[-1])
        u = r.first_reference_deg
        th, om = (MODEL.A[0, 0] * th + MODEL.A[0, 1] * om + MODEL.B[0] * u,
                  MODEL.A[1, 0] * th + MODEL.A[1, 1] * om + MODEL.B[1] * u)
        prev = u
    assert kinds.count("kept") >= 20 and kinds.count("daqp") >= 3, kinds


def test_a_wrong_active_set_is_not_certified() -> None:
    """Kept rows that do not bind (a face far away held at its bound), or whose multiplier has
    the wrong sign, give no answer; the right ones give the one-shot optimum."""
    d = dense.build_dense(MODEL, REGION, 50.0, H, LO, HI, 1.0, 0.05, 0.25)
    kept = KeptActiveSet(d)
    th, om = HOME + np.array([4.0, -3.0, 2.0]), np.zeros(3)
    ft, fo = d.free(th, om)
    target = HOME + np.array([6.0, 2.0, -5.0])
    f = d.cost(ft, fo, np.broadcast_to(target, (H, 3)), 1e4)
    lo, hi = d.bounds(th, om, target, th, ft, fo)
    kept.reached()
    z = kept.optimum(f, lo, hi)
    assert z is not None
    assert np.abs(z[: 3 * H].reshape(H, 3) - _one_shot(d, f, lo, hi)).max() <= 1e-6
    n = d.n
    face = n + d.rows_region.start  # the first region row, far from this motion
    lam = np.zeros(len(lo))
    lam[[*np.flatnonzero(d.sense[n:] == dense.EQUALITY) + n,
         *range(n + d.rows_terminal, n + d.rows_terminal + 6)]] = -1.0
    lam[face] = 1.0  # held at its upper bound: the motion is pulled onto it
    kept.keep(lam)
    assert kept.optimum(f, lo, hi) is None
    lam[face] = 0.0
    lam[n + d.rows_terminal] = 1.0  # a terminal row at its upper bound (+∞): nothing to hold
    kept.keep(lam)
    assert kept.optimum(f, lo, hi) is None
