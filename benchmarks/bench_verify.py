"""The runtime's plan verification before torque-on (``motion/plan_check.py``), same run.

Ours: :class:`PlanVerifier.verify` on the paper's MVN plan (N = 150): the exact ZOH motion
at 10 instants per interval plus the settling tail (1,5xx points), each looked up in the
workspace's certified set (8 table reads per point), with the limit, step and speed checks.
Baseline: the exact pointwise checks of the same points (FK continuation from the nearest
grid node, ζ, closed-form link distances: ``core/workspace_check.check_points``), the
other way a runtime could decide feasibility. Best of several, wall time, shared machine.
"""

from __future__ import annotations

import numpy as np

from benchmarks.common import Row, timeit
from spm_console.config.load import load_profile
from spm_console.config.models import link_model_of, model_of, servo_model_of
from spm_console.core.plan_rules import POINTS_PER_INTERVAL
from spm_console.core.planning.mvn import solve_mvn
from spm_console.core.regions.choice import region_containing
from spm_console.core.servo.model import simulate_continuous
from spm_console.core.workspace.check import check_points
from spm_console.motion.plan_check import PlanVerifier
from spm_console.motion.segments import Segment
from spm_console.store.workspace_cache import load_or_build

START = np.array([127.53, 83.23, 85.25])
GOAL = np.array([66.80, 155.00, 131.48])


def run() -> list[Row]:
    prof = load_profile("profiles/agile_wrist.toml")
    ws, _ = load_or_build(prof)
    plan = solve_mvn(servo_model_of(prof), START, GOAL, 150,
                     region_containing(ws, START, GOAL)).to_plan("mvn")
    verifier = PlanVerifier(prof, ws)
    segs = [Segment("plan", plan)]
    check = verifier.verify(segs)
    ours = timeit(lambda: verifier.verify(segs), repeat=20)
    x0 = np.column_stack([plan.reference_deg[0], np.zeros(3)])
    _, xs = simulate_continuous(prof.servo.p, prof.servo.ts_s, x0, plan.reference_deg,
                                POINTS_PER_INTERVAL)
    model, links = model_of(prof), link_model_of(prof)
    base = timeit(lambda: check_points(ws, model, links, xs[..., 0]), repeat=3)
    return [Row("verify: paper MVN N=150 before torque-on", ours * 1e3, "ms", "≤ 50 ms",
                baseline=base * 1e3, passed=ours <= 0.050,
                note=f"{check.points} simulated points (10 per interval + settling tail) in the "
                     "certified set, limits, steps, speeds; baseline = exact FK/ζ/link checks "
                     "of the same motion")]
