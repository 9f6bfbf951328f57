"""Optimal servo references (paper Sec. V): MVN (30) and minimum time (31).

Pure: numpy/scipy/OSQP/Clarabel only. Angles in degrees, speeds in deg/s, time in s.
"""

from spm_console.core.plan_report import ConstraintReport
from spm_console.core.planning.mintime import MintimeResult, solve_mintime, solve_mintime_problem
from spm_console.core.planning.mvn import solve_mvn, solve_problem
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.planning.result import PlanResult

__all__ = ["ConstraintReport", "MintimeResult", "PlanProblem", "PlanResult", "solve_mintime",
           "solve_mintime_problem", "solve_mvn", "solve_problem"]
