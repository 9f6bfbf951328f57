"""The QP solvers of the planner behind one interface: :class:`~.base.QpSolver` solves the
reduced QP (equalities + chosen pool rows) and answers a :class:`~.base.QpSolution`, which
computes its own primal and dual residuals and duality gap."""
