"""OSQP on the sparse follow QP (:mod:`spm_console.core.planning.follow.qp`): the follow
solver's settings and its OSQP passes. Degrees, deg/s, seconds.

OSQP runs at tolerance 1e-3 with polishing (exact when it finds the active set); only when
that answer is unpolished or fails the check does it go on, from the same iterate, at 1e-4
and then 1e-6 (``FollowSettings.tolerances``), within ``time_limit_s`` if set.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import osqp
from numpy.typing import NDArray

from spm_console.core.planning.follow.qp import FollowMatrices, fill_bounds, linear_cost, predict
from spm_console.core.servo.model import ServoModel

F = NDArray[np.float64]

#: OSQP's own "no time limit" (its default), s.
NO_TIME_LIMIT_S = 1e10
#: How every ``Solved.reason`` of a solve that ran out of its time limit begins.
OUT_OF_TIME = "out of time"


def out_of_time(limit_s: float, iterations: int) -> str:
    """The reason of a solve stopped by its ``limit_s`` time limit (s) after ``iterations``."""
    return f"{OUT_OF_TIME} ({limit_s * 1e3:g} ms) after {iterations} iterations"


@dataclass(frozen=True)
class FollowWeights:
    """Weights of the follow cost (the MVN term Σ‖θ̇‖² has weight 1, in (deg/s)²)."""

    track: float = 400.0
    """w, 1/s²: stage tracking Σ‖θ(k) − t(k)‖²; √w ≈ tracking bandwidth in rad/s."""
    terminal: float = 1e4
    """ρ, deg/s²: exact L1 penalty on θ(H) − t; above the terminal multiplier, θ(H) = t
    whenever reachable."""


@dataclass(frozen=True)
class FollowSettings:
    """Settings of the follow solver (the tolerances and OSQP's own: its OSQP passes)."""

    backend: Literal["daqp", "osqp"] = "daqp"
    """'daqp': the condensed QP by DAQP first, OSQP when it does not answer; 'osqp': OSQP only."""
    tolerances: tuple[float, ...] = (1e-3, 1e-4, 1e-6)
    """OSQP eps_abs = eps_rel of the passes: the first (loose: polishing makes its answer
    exact when it finds the active set), then each next one only when the answer so far
    fails the check, continuing from the same iterate."""
    polish: bool = True
    """Polish the ADMM point on its active set (exact answers, a factorization more)."""
    max_iter: int = 4000
    time_limit_s: float | None = None
    """Wall-time budget of one :meth:`FollowSolver.solve` call's OSQP passes together, s
    (None: none); a solve that runs out of it fails (status 'failed', the previous plan goes on)."""
    check_every: int = 5
    """Iterations between OSQP termination checks."""
    rho: float = 0.1
    """OSQP's initial ADMM step."""
    adapt_every: int = 25
    """Iterations between OSQP's step (ρ) adaptations."""


@dataclass(frozen=True)
class Solved:
    """What a backend's solve ended with (OSQP's passes, or DAQP's one solve)."""

    status: str
    """OSQP's status of the last pass."""
    iterations: int
    """Of every pass together."""
    x: F
    y: F
    theta_deg: F
    """(H+1, 3) the model's θ under ``reference_deg``."""
    omega_degps: F
    """(H+1, 3) … its θ̇."""
    reference_deg: F
    """(H, 3) θ*."""
    reason: str
    """Empty when the answer passed the check; 'infeasible'; or why it failed."""

    @property
    def timed_out(self) -> bool:
        """Stopped by the time limit (its reason, from :func:`out_of_time`)."""
        return self.reason.startswith(OUT_OF_TIME)


class OsqpFollow:
    """The sparse follow QP in one OSQP workspace (set up here, vectors updated per solve)."""

    def __init__(self, mats: FollowMatrices, model: ServoModel, settings: FollowSettings,
                 weights: FollowWeights, check: Callable[[F, F], str], lo: F, hi: F) -> None:
        self.mats, self.model, self.settings = mats, model, settings
        self._check, self._lo, self._hi = check, lo, hi
        self.solver = solver = osqp.OSQP()
        m = mats
        st = settings
        opts: dict[str, Any] = {
            "verbose": False, "eps_abs": st.tolerances[0], "eps_rel": st.tolerances[0],
            "eps_prim_inf": 1e-7, "eps_dual_inf": 1e-7, "polishing": st.polish,
            "polish_refine_iter": 3, "max_iter": st.max_iter, "warm_starting": True,
            "check_termination": st.check_every, "adaptive_rho_interval": st.adapt_every, "rho": st.rho,
            "scaled_termination": False,
        }
        if st.time_limit_s is not None:
            opts["time_limit"] = float(st.time_limit_s)
        q0 = linear_cost(m.layout, np.zeros((m.layout.H, 3)), weights.track, weights.terminal)
        lo0, hi0 = fill_bounds(m, self.model, np.zeros(3), np.zeros(3), np.zeros(3))
        solver.setup(m.P, q0, m.A, lo0, hi0, **opts)

    def prepare(self, q: F, lo: F, hi: F, x: F | None, y: F | None) -> None:
        """The vectors of the next solve and its start (zeros when ``x``/``y`` are None)."""
        self.solver.update(q=q, l=lo, u=hi)
        L = self.mats.layout
        self.solver.warm_start(x=np.zeros(L.n) if x is None else x,
                               y=np.zeros(L.m) if y is None else y)

    def run(self, th0: F, om0: F, t0: float, timed: bool = True) -> Solved:
        """OSQP at the loose tolerance, then — only while its answer does not pass the check
        (polishing failed) — on from the same iterate at the tighter ones (within the time
        limit when ``timed``).

        Returns the last pass's answer (or the best checked one)."""
        tols = self.settings.tolerances
        it = 0
        status = ""
        reason = ""
        x = y = th = om = ref = np.zeros(0)
        best: tuple[str, F, F, F, F, F] | None = None  # a checked but unpolished answer
        limit = self.settings.time_limit_s if timed else None
        if not timed and self.settings.time_limit_s is not None:
            self.solver.update_settings(time_limit=NO_TIME_LIMIT_S)
        for n, tol in enumerate(tols):
            if n:
                self.solver.update_settings(eps_abs=tol, eps_rel=tol)
            if limit is not None:
                left = limit - (time.perf_counter() - t0)
                if left <= 0:
                    reason = out_of_time(limit, it)
                    break
                self.solver.update_settings(time_limit=left)
            res = self.solver.solve(raise_error=False)
            status = str(res.info.status)
            it += int(res.info.iter)
            if status.startswith("primal infeasible"):
                reason = "infeasible"
                break
            if status not in ("solved", "solved inaccurate"):
                reason = f"the follow QP did not converge ({status})"
                continue
            x = np.asarray(res.x, float)
            y = np.asarray(res.y, float)
            ref, _, _ = self.mats.layout.unpack(x)
            ref = np.clip(ref, self._lo, self._hi)  # round-off beyond a servo limit
            th, om = predict(self.model, th0, om0, ref)
            reason = self._check(th, om)
            if reason:
                continue
            # the loosest pass's raw point is rough: prefer a polished or a tighter answer
            if int(res.info.status_polish) == 1 or n > 0 or not self.settings.polish:
                break
            best = (status, x, y, th, om, ref)
        if len(tols) > 1:
            self.solver.update_settings(eps_abs=tols[0], eps_rel=tols[0])
        if reason and reason != "infeasible" and best is not None:
            status, x, y, th, om, ref = best
            reason = ""
        return Solved(status, it, x, y, th, om, ref, reason)

