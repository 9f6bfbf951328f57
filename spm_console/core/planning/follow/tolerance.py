"""The follower's one tolerance, shared by the solver, the runtime and the console (no solver
imported here: the runtime and the console load this without osqp)."""

from __future__ import annotations

#: A state or target lies inside a region (and a target is not clamped) when it violates no
#: half-space, servo limit or speed bound by more than this (deg, deg/s). It is the follow
#: solver's final check: OSQP meets its rows only to its own tolerance, so the solver keeps
#: plans whose samples lie up to this far outside, and the runtime plans from, and heads for,
#: exactly what the solver accepts; the console words a target "clamped" beyond it. Not the
#: membership tolerance of planning (:data:`~spm_console.core.polytope.region.INSIDE_TOL_DEG`).
FOLLOW_TOL_DEG = 1e-6
