"""Planning benchmarks: MVN (30) and minimum time (31) against cvxpy, same run.

Baselines are the same problems written in cvxpy (``tests/support/reference_qp.py``) and
solved by cvxpy's default solver choice, timed from definition to solution like the
paper's CVX figures (25 s and 85 s). The minimum-time baseline is the paper's search:
bisection started at N = 100, one cvxpy solve per N. Timings are wall times (best of a
few) on a shared machine: expect noise.

Problems: the paper's MVN experiment in the region the workspace module builds around
the segment (the goal lies outside the cached P with our link model); the paper's
minimum-time experiment in the grid box 65..155° (with our link model the segment passes
within Δ of a singular grid node, so no convex region of the workspace holds both ends —
``plan mintime`` refuses it) and, with a 61-half-space polytope, a region-constrained one.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from benchmarks.common import Row, timeit
from spm_console.config.load import load_profile
from spm_console.core.planning.mintime import solve_mintime_problem
from spm_console.core.planning.mvn import solve_problem
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.planning.qp_build import Pool, equalities
from spm_console.core.planning.solvers.osqp_qp import OsqpQp
from spm_console.core.polytope.region import Region
from spm_console.core.servo.model import discretize
from spm_console.errors import SpmError
from tests.support.reference_qp import solve_reference

START = np.array([127.53, 83.23, 85.25])
GOAL = np.array([66.80, 155.00, 131.48])
START_MT = np.array([70.0, 90.0, 80.0])


def _mvn_region(profile_path: str = "profiles/agile_wrist.toml") -> tuple[Region, str]:
    try:
        from spm_console.core.regions.choice import region_containing
        from spm_console.store.workspace_cache import load_or_build

        ws, _ = load_or_build(load_profile(profile_path))
        return region_containing(ws, START, GOAL), "workspace region around the segment"
    except SpmError as exc:  # the benchmark still runs, on the box
        return Region.box(65.0, 155.0), f"grid box (workspace unavailable: {exc})"


def _polytope() -> Region:
    rng = np.random.default_rng(0)
    n = rng.normal(size=(55, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    pts = np.array([START_MT, GOAL])
    b = (n @ pts.T).max(1) + rng.uniform(0.0, 20.0, 55)
    b[:6] = (n[:6] @ pts.T).max(1)
    box = Region.box(65.0, 155.0)
    return Region(np.vstack([box.A, n]), np.concatenate([box.b, b]))


def cvxpy_bisection(pb: PlanProblem, n_hi: int = 100) -> tuple[int, int, float]:
    """The paper's search: bisection from N = 100 with cvxpy's default solver."""
    t0 = time.perf_counter()
    qps = 0
    hi = n_hi
    while solve_reference(pb.with_steps(hi), solver=None).status != "optimal":
        qps += 1
        hi *= 2
    qps += 1
    lo = 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        qps += 1
        if solve_reference(pb.with_steps(mid), solver=None).status == "optimal":
            hi = mid
        else:
            lo = mid
    return hi, qps, time.perf_counter() - t0


def run() -> list[Row]:
    warnings.filterwarnings("ignore")
    rows: list[Row] = []
    prof = load_profile("profiles/agile_wrist.toml")
    model = discretize(prof.servo.p, prof.servo.ts_s, prof.servo.discretization)
    lim = {"ref_lo_deg": np.full(3, 60.0), "ref_hi_deg": np.full(3, 160.0)}
    region, src = _mvn_region()

    # MVN, paper experiment, N = 150
    pb = PlanProblem(model, START, GOAL, 150, region, **lim)
    ours = timeit(lambda: solve_problem(pb), repeat=7)
    res = solve_problem(pb)
    ref = solve_reference(pb, solver=None)
    base = timeit(lambda: solve_reference(pb, solver=None), repeat=3)
    rel = abs(res.cost - ref.cost) / ref.cost
    rows.append(Row("plan: MVN N=150 (paper), solve", ours * 1e3, "ms", "<= 10 ms, >= 5x cvxpy",
                    base * 1e3, ours <= 0.010 and base / ours >= 5,
                    f"{src}, {region.halfspaces} half-spaces; {res.info['method']}; cvxpy "
                    f"({ref.solver}) cost rel. diff {rel:.1e}; max speed between samples "
                    f"{res.check.max_speed_between_degps:.2f} deg/s, at samples "
                    f"{res.check.max_speed_samples_degps:.2f}"))

    # OSQP's plain figure: the whole QP (every region row) in one OSQP solve
    eq, pool = equalities(pb), Pool(pb)
    every = np.arange(pool.m)
    plain = timeit(lambda: OsqpQp().solve(eq, pool, every, None), repeat=3)
    o = OsqpQp().solve(eq, pool, every, None)
    rows.append(Row("plan: MVN N=150, OSQP on the full QP", plain * 1e3, "ms", "info",
                    None, None, f"{pool.m} inequality rows, {o.iterations} iterations, status "
                    f"'{o.detail}', polished={o.polished}; screening + exact KKT replace it"))

    # minimum time, paper experiment (grid box) and with a 61-half-space polytope
    for name, reg in (("box", Region.box(65.0, 155.0)), ("61-plane polytope", _polytope())):
        mt = PlanProblem(model, START_MT, GOAL, 2, reg, 50.0, **lim)
        t_ours = timeit(lambda mt=mt: solve_mintime_problem(mt), repeat=3)  # type: ignore[misc]
        r = solve_mintime_problem(mt)
        n_b, q_b, t_b = cvxpy_bisection(mt)
        rows.append(Row(f"plan: min time vmax=50 ({name}), total", t_ours * 1e3, "ms",
                        "<= 200 ms, >= 5x cvxpy", t_b * 1e3, t_ours <= 0.2 and t_b / t_ours >= 5,
                        f"N* = {r.N} ({r.N * model.ts:.2f} s; paper 76 with its eq. (35) and P), "
                        f"{r.qp_count} QPs, N*-1 certificate radius "
                        f"{r.certificate.excluded_radius if r.certificate else float('nan'):.2g}; "
                        f"cvxpy bisection from N=100: N = {n_b}, {q_b} QPs"))

    # a hard case: thin region, references limited, constraints between samples
    from tests.support.planning_cases import slab  # the test suite's hand-made regions

    hard = PlanProblem(model, START, GOAL, 150, slab(START, GOAL, 0.1), None, 4,
                       ref_lo_deg=np.full(3, 60.0), ref_hi_deg=np.array([160.0, 155.05, 160.0]))
    t_h = timeit(lambda: solve_problem(hard), repeat=3)
    rh = solve_problem(hard)
    t_hb = timeit(lambda: solve_reference(hard, solver=None), repeat=1)
    t_ho = timeit(lambda: solve_problem(hard, backend="osqp"), repeat=1)
    ro = solve_problem(hard, backend="osqp")
    rows.append(Row("plan: MVN hard case (slab, K=4, ref limits)", t_h * 1e3, "ms", "info",
                    t_hb * 1e3, None, f"{rh.info['method']}; with the OSQP backend "
                    f"{t_ho * 1e3:.0f} ms ({ro.info['method']})"))

    # MVN scaling in N
    for n in (50, 100, 200, 500, 1000):
        pn = PlanProblem(model, START, GOAL, n, region, **lim)
        t_n = timeit(lambda pn=pn: solve_problem(pn), repeat=3)  # type: ignore[misc]
        b_n = timeit(lambda pn=pn: solve_reference(pn, solver=None), repeat=1) if n <= 500 else None
        rows.append(Row(f"plan: MVN scaling N={n}", t_n * 1e3, "ms", "info",
                        None if b_n is None else b_n * 1e3, None))
    return rows
