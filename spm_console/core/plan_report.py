"""What a plan records about itself: the constraint report and minimum time's N*−1 record.

Plain frozen dataclasses, so :class:`~spm_console.core.plan.Plan` can hold them
without importing the planners (the planners import the plan). Degrees, deg/s, seconds.
How they are written to and read from a plan file: :mod:`spm_console.store.plan_schema`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any


@dataclass(frozen=True)
class ConstraintReport:
    """Worst violations of (30b–f) at the samples and of (30d, e) between samples.

    Read from a plan file, a number the file does not hold (or holds as null) is NaN,
    ``points_per_interval`` 0 and ``ok`` False.
    """

    start_error_deg: float
    """max |θ(0) − start| (always 0: the simulation starts there)."""
    goal_error_deg: float
    """max |θ(N) − goal|, deg."""
    final_speed_degps: float
    """max |θ̇(N)|, deg/s."""
    model_mismatch: float
    """max |optimizer states − simulated states| (deg and deg/s)."""
    region_violation_deg: float
    """Largest distance outside P at the samples, deg."""
    speed_excess_degps: float
    """max(|θ̇(k)| − v_max, 0) at the samples, deg/s (0 without a bound)."""
    reference_excess_deg: float
    """Largest excursion of θ*(k) beyond the optional reference limits, deg."""
    max_speed_samples_degps: float
    """max |θ̇(k)| at the samples, deg/s."""
    max_speed_between_degps: float
    """max |θ̇(t)| of the continuous motion (27), deg/s."""
    speed_excess_between_degps: float
    """max(|θ̇(t)| − v_max, 0) between samples, deg/s."""
    region_violation_between_deg: float
    """Largest distance outside P of the continuous motion, deg."""
    intersample_violation: float
    """With K > 1: worst region (deg) or speed (deg/s) violation at the enforced sub-samples."""
    points_per_interval: int
    ok: bool
    """All sample constraints hold to the planner's tolerance (1e-6), and the runtime's rules
    hold (:attr:`runtime_rule` is empty)."""
    runtime_rule: str = ""
    """The first of the runtime's rules (:class:`~spm_console.core.plan_rules.Rule`, its
    value) the motion breaks, checked as the runtime will (all but the workspace's
    certification, which the planner's caller checks); empty when every rule holds. Read
    from a plan file written before the field existed: empty (the runtime checks again)."""

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


#: Fields of :class:`ConstraintReport` that are numbers (deg, deg/s).
REPORT_NUMBERS = ("start_error_deg", "goal_error_deg", "final_speed_degps", "model_mismatch",
                  "region_violation_deg", "speed_excess_degps", "reference_excess_deg",
                  "max_speed_samples_degps", "max_speed_between_degps",
                  "speed_excess_between_degps", "region_violation_between_deg",
                  "intersample_violation")


@dataclass(frozen=True)
class Certificate:
    """A checked Farkas certificate of primal infeasibility."""

    residual_l1: float
    """‖Aᵀy‖₁ with y scaled to bᵀy = −1."""
    cone_violation: float
    """Largest negative entry of y on the non-negative cone (0 for an exact certificate)."""
    excluded_radius: float
    """No point with ‖x‖∞ below this satisfies the constraints (∞ for an exact certificate)."""
    rows: int
    """Constraint rows the certificate covers (equalities + screened pool rows)."""
    valid: bool
    solver: str = "clarabel"

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class SearchStep:
    """One horizon examined by the minimum-time search."""

    N: int
    verdict: str
    """'solved' or 'infeasible'."""
    method: str
    """How the QP was decided (e.g. 'clarabel+active-set')."""
    seconds: float
    """Wall time of this step, s."""

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class InfeasibilityRecord:
    """Minimum time's proof of optimality: N*−1 steps are infeasible."""

    N: int
    """The horizon proven infeasible, N*−1."""
    certificate: Certificate | None
    """Farkas certificate for N (None when N* is the smallest N the search may try)."""
    search: tuple[SearchStep, ...] = ()
    """Every N examined, in order."""
    search_seconds: float = float("nan")
    """Wall time of the whole search, s."""
    scope: str = ""
    """What the proof covers when it is not the whole problem: a plan across regions is
    proven infeasible for its region sequence and switch samples only (empty: one region)."""

    def describe(self) -> str:
        """One line for people: what is proven about N − 1 steps."""
        cert = self.certificate
        if cert is None:
            return f"N−1 = {self.N}: no infeasibility certificate (the search tries N ≥ 2 only)"
        r = cert.excluded_radius
        return (f"N−1 = {self.N} infeasible" + (f" {self.scope}" if self.scope else "")
                + ": Farkas certificate excludes ‖x‖∞ < "
                + ("∞" if math.isinf(r) else f"{r:.3g}") + ("" if cert.valid else " (NOT valid)"))
