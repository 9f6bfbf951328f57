"""Identify a wrist as built from the gravity an IMU on its platform measures at rest.

The model is :mod:`~spm_console.core.commissioning.gravity`'s: horn offsets δ, the IMU's mount,
the base's tilt and each leg's arcs, through the unique FK of (4). The fit is Levenberg–Marquardt
(scipy's ``least_squares``, MINPACK) on the unit-vector residuals g_k(p) − ĝ_k with the exact
Jacobian (implicit differentiation of (4) with J1 (11) and J2 (12)), from a start p0, with some
parameters (or the horns' common mode) held at given values, and only along the directions
:mod:`~spm_console.core.commissioning.observability`'s rule lets the data decide: the others keep
p0's values. The split is made at p0, then again at the solution until it holds as many
directions as the fit did.

Standard errors: s² (JᵀJ)⁻¹ on the fitted subspace, s² the residual variance per component
(a direction has two degrees of freedom: 2K − m of them for K poses and m fitted directions);
the expected ones use the stated noise instead of s (noise-free data still get an honest figure).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from spm_console.core.commissioning import observability as obs
from spm_console.core.commissioning.gravity import PARAMETERS, AsBuilt, Evaluation, evaluate
from spm_console.core.kinematics.model import SpmModel
from spm_console.errors import BadInputError, SolverError

F = NDArray[np.float64]
N_P = len(PARAMETERS)
MAX_SPLITS = 4
"""Rounds of split-then-fit at most."""


@dataclass(frozen=True)
class FittedParameter:
    """One parameter of the fit (degrees)."""

    name: str
    value_deg: float
    """Fitted value (the prior's along held directions; the given one when fixed)."""
    std_deg: float
    """Standard error from the residuals (NaN when undetermined, 0 when fixed)."""
    std_expected_deg: float
    """Standard error at the stated noise (NaN when undetermined, 0 when fixed)."""
    status: obs.Status
    held_share: float
    """Share of it in the directions held at the prior (0 to 1)."""


@dataclass(frozen=True)
class CommissioningFit:
    """What the gravity data say about the wrist as built."""

    as_built: AsBuilt
    """The fitted values (the prior along held directions)."""
    parameters: tuple[FittedParameter, ...]
    singular_values: tuple[float, ...]
    """Singular values of the scaled identification Jacobian Js over the free parameters at the
    solution, largest first (1/σ_k: the standard error along v_k in prior spreads)."""
    held: tuple[obs.Direction, ...]
    """Directions the data do not determine (σ_k < 1), held at the prior, weakest first."""
    imprecise: tuple[obs.Direction, ...]
    """Fitted directions whose standard error at the stated noise exceeds the resolution."""
    undetermined_named: tuple[str, ...]
    """Named combinations (:data:`~.observability.NAMED`) held or imprecise."""
    residual_rms_deg: float
    """RMS angle between the fitted and the measured gravity directions."""
    residual_max_deg: float
    residual_std_deg: float
    """s: the residuals' standard deviation per direction component (NaN without redundancy)."""
    noise_deg: float
    resolution_deg: float
    poses: int
    converged: bool
    message: str

    def parameter(self, name: str) -> FittedParameter:
        return self.parameters[PARAMETERS.index(name)]

    def named(self, status: obs.Status) -> tuple[str, ...]:
        """Names of the parameters with this status."""
        return tuple(p.name for p in self.parameters if p.status == status)


def _measured(theta_meas_deg: F, gravity: F) -> tuple[F, F]:
    th = np.asarray(theta_meas_deg, float)
    g = np.asarray(gravity, float)
    if th.ndim != 2 or th.shape[1] != 3 or g.shape != th.shape or len(th) == 0:
        raise BadInputError("poses: joint angles and gravity vectors are (K, 3) arrays of the "
                            f"same K ≥ 1, got {th.shape} and {g.shape}")
    if not (np.isfinite(th).all() and np.isfinite(g).all()):
        raise BadInputError("poses: every joint angle and gravity component must be finite")
    n = np.linalg.norm(g, axis=1)
    if (n <= 0.0).any():
        raise BadInputError(f"gravity: pose {int(np.argmin(n))} measured a zero vector")
    return np.radians(th), g / n[:, None]


def angles_deg(a: F, b: F) -> F:
    """Angle between unit vectors row by row, deg (atan2: exact for small angles)."""
    return np.asarray(np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=1),
                                            (a * b).sum(axis=1))))


class _Model:
    """The measurement model on one data set, degrees, with the last evaluation kept."""

    def __init__(self, model: SpmModel, theta: F) -> None:
        self.model, self.theta = model, theta
        self.last: Evaluation | None = None

    def at(self, x_deg: F) -> Evaluation:
        p = np.radians(x_deg)
        if self.last is None or not np.array_equal(self.last.p, p):
            self.last = evaluate(self.model, p, self.theta, warm=self.last)
        return self.last

    def residual(self, x_deg: F, g_meas: F) -> F:
        """g(x) − ĝ (3K,); 2 in every component (beyond any unit vectors' difference) where x
        has no unique FK, so that the fit's step is refused."""
        try:
            return np.asarray((self.at(x_deg).gravity - g_meas).ravel())
        except SolverError:
            return np.full(g_meas.size, 2.0)

    def jac_deg(self, x_deg: F) -> F:
        J = self.at(x_deg).jacobian
        assert J is not None
        return np.asarray(J.reshape(-1, N_P) * (math.pi / 180.0))


def fit_as_built(
    model: SpmModel,
    theta_meas_deg: F,
    gravity: F,
    start: AsBuilt | None = None,
    fixed: Mapping[str, float] | None = None,
    spread: AsBuilt = obs.DEFAULT_SPREAD,
    noise_deg: float = obs.DEFAULT_NOISE_DEG,
    resolution_deg: float = obs.DEFAULT_RESOLUTION_DEG,
) -> CommissioningFit:
    """Fit the wrist as built to K static poses.

    ``theta_meas_deg`` (K, 3): the joint angles the servos report; ``gravity`` (K, 3): the
    specific force the IMU measures at rest in its own axes (any scale: only its direction is
    used). ``start``: the prior p0 (default: the model's arcs, everything else zero), kept along
    the directions the data do not determine; ``fixed``: parameters (or
    :data:`~.observability.COMBINATIONS`) held at these values, deg; ``spread``: the prior's
    spread of each parameter, deg; ``noise_deg``: σ of one component of a measured direction;
    ``resolution_deg``: the largest standard error of a parameter called determined.
    """
    theta, g_meas = _measured(theta_meas_deg, gravity)
    if not (noise_deg > 0.0 and resolution_deg > 0.0):
        raise BadInputError("noise_deg and resolution_deg must be positive")
    sp_deg = obs.spread_of(spread)
    x0 = np.degrees((start or AsBuilt.of_model(model)).vector_rad())
    C, b = obs.constraints(fixed or {})
    if len(C):
        x0 = x0 + np.linalg.pinv(C) @ (b - C @ x0)
    N_q = obs.null_basis(C * sp_deg)  # free directions in spreads
    m = _Model(model, theta)
    x, split, sol = x0.copy(), None, None
    for _ in range(MAX_SPLITS):
        new = obs.split(m.jac_deg(x), N_q, sp_deg, noise_deg)
        if split is not None and new.fitted.shape == split.fitted.shape:
            break  # the solution splits the parameters as the fit did
        split = new
        B = sp_deg[:, None] * split.fitted  # fitted directions, deg per unit
        q = (x - x0) / sp_deg
        x = x0 + B @ (split.fitted.T @ q)  # back to the prior along the held ones
        if B.shape[1] == 0:
            break
        base = x.copy()

        def resid(y: F, base: F = base, B: F = B) -> F:
            return m.residual(base + B @ y, g_meas)

        def jac(y: F, base: F = base, B: F = B) -> F:
            return m.jac_deg(base + B @ y) @ B

        sol = least_squares(resid, np.zeros(B.shape[1]), jac=jac, method="lm",
                            xtol=1e-14, ftol=1e-14, gtol=1e-14, max_nfev=200)
        x = base + B @ sol.x
    assert split is not None
    for name, value in (fixed or {}).items():  # exactly the given values
        if name in PARAMETERS:
            x[PARAMETERS.index(name)] = value
    at_x = obs.split(m.jac_deg(x), N_q, sp_deg, noise_deg)
    return _result(m, x, g_meas, split, at_x.singular_values, sp_deg, noise_deg, resolution_deg,
                   sol)


def _result(m: _Model, x: F, g_meas: F, split: obs.Split, sv: F, sp_deg: F, noise_deg: float,
            resolution_deg: float, sol: object) -> CommissioningFit:
    """The fit's report: ``split`` is the one the last round fitted along (so the held
    directions kept the prior exactly), ``sv`` the singular values at the solution."""
    ev, J = m.at(x), m.jac_deg(x)
    K, n_fit = len(g_meas), split.fitted.shape[1]
    r = ev.gravity - g_meas
    dof = 2 * K - n_fit
    s = math.sqrt(float((r * r).sum()) / dof) if dof > 0 else math.nan
    cov = obs.covariance(J, split, sp_deg, s if dof > 0 else 0.0)
    cov_exp = obs.covariance(J, split, sp_deg, math.radians(noise_deg))
    params = []
    for j, name in enumerate(PARAMETERS):
        e = np.eye(N_P)[j]
        share = obs.held_share(split, sp_deg, e)
        fixed = bool(np.linalg.norm(split.fitted[j]) < 1e-12 and share < 1e-12)
        std, std_e = math.sqrt(max(cov[j, j], 0.0)), math.sqrt(max(cov_exp[j, j], 0.0))
        status: obs.Status = ("fixed" if fixed else
                              "undetermined" if share > obs.SHARE_TOL else
                              "imprecise" if std_e > resolution_deg else "determined")
        if status == "undetermined":
            std = std_e = math.nan
        if dof <= 0 and status != "fixed":
            std = math.nan
        params.append(FittedParameter(name, float(x[j]), std, std_e, status, share))
    ang = angles_deg(ev.gravity, g_meas)
    return CommissioningFit(
        as_built=AsBuilt.from_vector_rad(np.radians(x)), parameters=tuple(params),
        singular_values=tuple(float(v) for v in sv),
        held=obs.held_directions(split, sp_deg),
        imprecise=obs.imprecise_directions(cov_exp, resolution_deg),
        undetermined_named=obs.undetermined_named(split, sp_deg, cov_exp, resolution_deg),
        residual_rms_deg=float(np.sqrt(np.mean(ang**2))), residual_max_deg=float(ang.max()),
        residual_std_deg=math.degrees(s), noise_deg=noise_deg, resolution_deg=resolution_deg,
        poses=K, converged=sol is None or bool(getattr(sol, "success", False)),
        message="nothing to fit" if sol is None else str(getattr(sol, "message", "")),
    )
