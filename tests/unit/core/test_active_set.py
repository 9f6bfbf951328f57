"""The exact active-set refinement: its KKT certificate against cvxpy, its repairs of a wrong
working set, and its refusal of an over-determined one."""

from __future__ import annotations

import numpy as np
import pytest

from spm_console.core.planning.active_set import PRIMAL_TOL, eqp, refine
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.planning.qp_build import Pool, equalities
from spm_console.core.polytope.region import Region
from tests.support.planning_cases import GOAL, MODEL, START, slab
from tests.support.reference_qp import solve_reference

LIMITS = {"ref_lo_deg": np.full(3, 60.0), "ref_hi_deg": np.array([160.0, 155.05, 160.0])}


def _cost(z: np.ndarray, N: int) -> float:
    """Σ‖θ̇(k)‖² of a z vector (the cost of (30))."""
    return float((z[: 6 * (N + 1)].reshape(N + 1, 6)[:, 3:] ** 2).sum())


def _z(ref_th: np.ndarray, ref_om: np.ndarray, ref_u: np.ndarray, N: int) -> np.ndarray:
    """The z vector (θ, θ̇ per sample, then θ*) of a reference solution."""
    return np.concatenate([np.hstack([ref_th, ref_om]).ravel(), ref_u[:N].ravel()])


@pytest.mark.parametrize("region, vmax", [
    (Region.box(60.0, 160.0), None),  # the reference's step limit binds
    (slab(START, GOAL, 0.1), 45.0),  # a thin slab, the speed bound and a reference limit bind
])
def test_the_certified_optimum_is_cvxpys(region: Region, vmax: float | None) -> None:
    """Seeded with the rows cvxpy's optimum holds at a bound (an independent proposer), the
    refinement certifies the KKT conditions itself and lands on cvxpy's optimum."""
    pb = PlanProblem(MODEL, START, GOAL, 100, region, vmax, 1, True, **LIMITS)
    eq, pool = equalities(pb), Pool(pb)
    ref = solve_reference(pb)
    assert ref.status == "optimal"
    assert ref.position_deg is not None and ref.velocity_degps is not None
    assert ref.reference_deg is not None
    gz = pool.values(_z(ref.position_deg, ref.velocity_degps, ref.reference_deg, pb.N))
    tol = 1e-5 * pool.scale
    up, dn = np.flatnonzero(gz >= pool.hi - tol), np.flatnonzero(gz <= pool.lo + tol)
    active = np.concatenate([up, dn])
    side = np.concatenate([np.ones(up.size, np.int64), -np.ones(dn.size, np.int64)])
    assert active.size > 0
    r = refine(eq, pool, active, side, max_solves=20)
    assert r.ok and r.z is not None
    assert r.max_violation <= PRIMAL_TOL and r.min_dual >= -1e-9
    assert _cost(r.z, pb.N) == pytest.approx(ref.cost, rel=1e-6)
    u = r.z[6 * (pb.N + 1):].reshape(pb.N, 3)
    assert np.abs(u - ref.reference_deg[: pb.N]).max() <= 1e-3


def test_a_wrong_row_in_the_working_set_leaves_it() -> None:
    """A reference-limit row held at its bound that the optimum does not touch has a
    wrong-signed multiplier: the refinement drops it and certifies the same optimum."""
    pb = PlanProblem(MODEL, START, GOAL, 60, Region.box(60.0, 160.0), None, 1, True, **LIMITS)
    eq, pool = equalities(pb), Pool(pb)
    free = refine(eq, pool, max_solves=20)
    assert free.ok and free.z is not None
    # the lower reference limit of joint 1 at sample 30: far from the optimum's references
    row = int(pool.offsets[4]) + 3 * (30 - pool.k0)
    assert row not in free.active
    forced = refine(eq, pool, np.append(free.active, row), np.append(free.side, -1))
    assert forced.ok and forced.z is not None and row not in forced.active
    assert forced.solves >= 2
    assert np.abs(forced.z - free.z).max() <= 1e-9


def test_an_over_determined_working_set_has_no_solution() -> None:
    pb = PlanProblem(MODEL, START, GOAL, 10, Region.box(60.0, 160.0), None, 1, True, **LIMITS)
    eq, pool = equalities(pb), Pool(pb)
    too_many = np.arange(eq.layout.n - eq.C.shape[0] + 1)
    assert eqp(eq, pool, too_many, np.ones_like(too_many)) is None
