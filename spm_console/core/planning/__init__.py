"""Optimal servo references (paper Sec. V): MVN (30) and minimum time (31).

Pure: numpy/scipy/OSQP/Clarabel only. Angles in degrees, speeds in deg/s, time in s.
"""

from spm_console.core.planning.mvn import solve_mvn, solve_problem
from spm_console.core.planning.problem import PlanProblem
from spm_console.core.planning.result import PlanResult
from spm_console.core.planning.verify import ConstraintReport

__all__ = ["ConstraintReport", "PlanProblem", "PlanResult", "solve_mvn", "solve_problem"]
