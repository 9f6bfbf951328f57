"""The condensed follow QP (:mod:`spm_console.core.planning.follow.dense`) in one DAQP
workspace, with the previous answer's active set tried first
(:mod:`spm_console.core.planning.follow.kept`). Degrees, deg/s."""

from __future__ import annotations

from dataclasses import dataclass

import daqp
import numpy as np
from numpy.typing import NDArray

from spm_console.core.planning.follow.dense import DenseFollow
from spm_console.core.planning.follow.kept import KeptActiveSet

F = NDArray[np.float64]

#: DAQP's exit flags this module tells apart (daqp's ``exitflag``).
DAQP_OPTIMAL, DAQP_INFEASIBLE, DAQP_TIME_LIMIT = 1, -1, -7


@dataclass(frozen=True)
class DenseAnswer:
    """One DAQP solve of the condensed follow QP."""

    flag: int
    """DAQP's exit flag (1: optimal; −1: infeasible; others: failed)."""
    reference_deg: F
    """(H, 3) θ*(0..H−1) (empty unless optimal)."""
    iterations: int
    kept: bool = False
    """The previous answer's active set, certified for this one (:mod:`~spm_console.core.
    planning.follow.kept`): no DAQP iteration was needed."""

    @property
    def status(self) -> str:
        if self.kept:
            return "kept: optimal (the previous active set, KKT-certified)"
        words = {DAQP_OPTIMAL: "optimal", DAQP_INFEASIBLE: "infeasible", -2: "cycling",
                 -3: "unbounded", -4: "iteration limit", DAQP_TIME_LIMIT: "time limit"}
        return f"daqp: {words.get(self.flag, f'exit flag {self.flag}')}"


class DaqpFollow:
    """The condensed follow QP in one DAQP workspace: factored once here (before the loop:
    the first solve in the loop costs no more than the next), vectors updated per solve, and
    each solve starts from the previous one's active set unless told to start cold."""

    def __init__(self, dense: DenseFollow, terminal_weight: float) -> None:
        self.dense = dense
        self.terminal_weight = float(terminal_weight)
        self._model = daqp.Model()
        # the constant bounds (the data's parts at 0: consistent, lo ≤ hi); each solve sets its own
        flag = self._model.setup(dense.H_cost, np.zeros(dense.n), dense.A, dense.hi, dense.lo,
                                 dense.sense.copy())
        code = int(flag[0] if isinstance(flag, tuple) else flag)
        if code < 0:
            raise ValueError(f"DAQP could not set up the follow QP (exit flag {code})")
        self._kept = KeptActiveSet(dense)

    def solve(self, theta_deg: F, omega_degps: F, targets: F, previous_deg: F,
              cold: bool = False, time_limit_s: float | None = None,
              elapsed: int = 1) -> DenseAnswer:
        """Solve for the state, per-sample targets (H, 3) (the last is the terminal one), the
        reference in use; ``time_limit_s``: DAQP's own budget (None: none); ``elapsed``:
        periods since the previous solve. The previous answer's active set, as it was and
        then moved by ``elapsed`` samples, is tried first (:mod:`~spm_console.core.planning.
        follow.kept`); DAQP solves when neither is certified."""
        d = self.dense
        ft, fo = d.free(theta_deg, omega_degps)
        f = d.cost(ft, fo, targets, self.terminal_weight)
        lo, hi = d.bounds(theta_deg, omega_degps, targets[-1], previous_deg, ft, fo)
        if cold:  # nothing from the previous answer: the guess "the target is reached"
            self._kept.reached()
        z = self._kept.optimum(f, lo, hi)
        if z is None and not cold and self._kept.known and self._kept.shift(elapsed):
            z = self._kept.optimum(f, lo, hi)
        if z is not None:
            return DenseAnswer(DAQP_OPTIMAL, z[: 3 * d.H].reshape(d.H, 3), 0, kept=True)
        self._model.settings = {"time_limit": 0.0 if time_limit_s is None
                                else max(float(time_limit_s), 1e-9)}
        if cold:
            self._model.update(f=f, bupper=hi, blower=lo, sense=d.sense.copy())
        else:
            self._model.update(f=f, bupper=hi, blower=lo)
        z, _, flag, info = self._model.solve()
        it = int(info["iterations"])
        if int(flag) != DAQP_OPTIMAL:
            self._kept.forget()
            return DenseAnswer(int(flag), np.zeros((0, 3)), it)
        self._kept.keep(np.asarray(info["lam"], float))
        return DenseAnswer(DAQP_OPTIMAL, np.asarray(z, float)[: 3 * d.H].reshape(d.H, 3), it)
