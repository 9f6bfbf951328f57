"""Where the wrist rests, from the platform's rotations an IMU measured while each leg alone was
nudged: the joint angles at rest and the IMU's mounting, without a jig.

A nudge dθ_i of leg i turns the platform from R(θ) to R(θ + dθ_i e_i) (the unique FK of (4),
continued from home); the IMU on the platform, mounted by R_m, measures the rotation between
its two readings in its own frame:

    r_i = R_mᵀ · log(R(θ)ᵀ R(θ + dθ_i e_i))                          (one nudge, exactly)

Three nudges give nine numbers for six unknowns (θ at rest, R_m). How each leg's axis of
rotation (dω/dθ_i = J1⁻¹ J2 e_i, eqs. 11, 12) lies in the platform's frame changes with θ, so
θ is determined; the fit is a least-squares problem started from a grid of poses (the mounting
of each start solved in closed form), and refused when two distinct poses explain the
rotations alike. The base's tilt plays no part (rotations between two readings).

Degrees at the interface, radians inside.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from spm_console.core.commissioning.gravity import built_model
from spm_console.core.kinematics.jacobian import jacobian
from spm_console.core.kinematics.model import SpmModel, newton, platform_axes
from spm_console.errors import SolverError

F = NDArray[np.float64]

#: The grid of starting poses: each joint at home and ± this, deg (27 starts).
START_SPREAD_DEG = 25.0
#: The starts (best first, their mounting solved) refined by least squares.
REFINED_STARTS = 4
#: Evaluations of one start's least squares (a start near the answer takes about five).
MAX_NFEV = 40
#: Two minima farther apart than this (deg, any joint) are two different explanations.
DISTINCT_DEG = 3.0
#: A second explanation is refused when its residual is within this factor of the best's.
AMBIGUOUS_FACTOR = 4.0
#: Noise floor of one measured rotation component, deg (the standard errors never assume less).
MIN_NOISE_DEG = 0.005


@dataclass(frozen=True)
class RestFit:
    """The joint angles at rest and the IMU's mounting that explain the nudges' rotations."""

    theta_deg: tuple[float, float, float]
    """The true joint angles at rest, deg."""
    theta_std_deg: tuple[float, float, float]
    """Their standard errors, deg (from the residuals, at least :data:`MIN_NOISE_DEG`)."""
    mount_rotvec_deg: tuple[float, float, float]
    """The IMU's orientation on the platform (rotation vector), deg."""
    residual_rms_deg: float
    """RMS of the nine residuals, deg."""
    runner_up_deg: float
    """The residual RMS of the best distinct other explanation, deg (inf: none)."""


def leg_axes(model: SpmModel, theta_rad: F) -> F:
    """Each leg's platform rotation axis per radian of its joint at θ (rad): (3 legs, 3) in the
    base frame, dω/dθ_i = J1⁻¹ J2 e_i (eqs. 11, 12); ValueError where θ has no pose."""
    r = model.track(np.asarray(theta_rad, float))
    if not r.ok or r.pose is None:
        raise ValueError(f"no pose at θ = {np.degrees(theta_rad).round(3).tolist()} deg: "
                         f"{r.reason}")
    v = platform_axes(r.pose.R, model.v_home)
    return np.asarray(jacobian(model.u, v, model.geom.w(np.asarray(theta_rad, float))).T, float)


#: Largest joint step a pose is found by Newton from a known one (no continuation), rad.
_NEWTON_STEP_RAD = math.radians(2.0)
#: Residual of (4) below which Newton's pose counts as found.
_NEWTON_TOL = 1e-10


class _Fk:
    """The unique FK (continued from home, eq. 4) of poses near each other: Newton from the
    last pose found when the step is small, else a continuation from it (or from home)."""

    def __init__(self, model: SpmModel) -> None:
        self.model = model
        self.theta: F | None = None
        self.R: F | None = None

    def pose(self, theta: F) -> F | None:
        th = np.asarray(theta, float)
        if self.theta is not None and self.R is not None:
            if np.abs(th - self.theta).max() <= _NEWTON_STEP_RAD:
                R = near(self.model, self.R, th[None])
                if R is not None:
                    self.theta, self.R = th, R[0]
                    return self.R
            r = self.model.track(th, self.theta, self.R, max_step=math.radians(5.0))
            if r.ok and r.pose is not None:
                self.theta, self.R = th, np.asarray(r.pose.R, float)
                return self.R
        r = self.model.track(th)  # from home, in 1° steps
        if not r.ok or r.pose is None:
            return None
        self.theta, self.R = th, np.asarray(r.pose.R, float)
        return self.R


def near(model: SpmModel, R0: F, thetas: F) -> F | None:
    """The poses (K, 3, 3) at joint angles ``thetas`` (K, 3) rad within a couple of degrees of
    the pose ``R0``: Newton on (4) from it (the branch it is on); None when one does not
    converge."""
    g = model.geom
    R, res = newton(g, g.w(thetas), np.repeat(R0[None], len(thetas), 0), model.v_home)
    return None if (res > _NEWTON_TOL).any() else R


def nudge_rotations(model: SpmModel, theta_rad: F, before_rad: F, after_rad: F,
                    fk: _Fk | None = None) -> F | None:
    """Each swing i's rotation from θ + before_i to θ + after_i (3, 3), rad, in the platform's
    frame: log(R(θ + before_i)ᵀ R(θ + after_i)); ``before``, ``after``: (3 swings, 3 joints)
    rad from θ (a swung leg's own step, and wherever the others were held), or (3,) for the
    swung leg's step alone (the others at θ). None where a pose does not exist."""
    fk = fk or _Fk(model)
    base = np.asarray(theta_rad, float)
    R0 = fk.pose(base)
    if R0 is None:
        return None
    ends = np.vstack([base + _steps(before_rad), base + _steps(after_rad)])
    R = near(model, R0, ends)
    if R is None:
        return None
    return np.asarray(Rotation.from_matrix(np.transpose(R[:3], (0, 2, 1)) @ R[3:]).as_rotvec(),
                      float)


def _steps(x: F) -> F:
    """(3 swings, 3 joints) from a (3,) step of each swung leg alone, or as given."""
    a = np.asarray(x, float)
    return np.diag(a) if a.ndim == 1 else a


def _mount_for(body: F, measured: F) -> F:
    """The rotation R_m (rotation vector, rad) that best turns the platform-frame rotations
    ``body`` into the measured ones (measured ≈ R_mᵀ body): Kabsch."""
    H = measured.T @ body  # Σ r_i b_iᵀ: R_mᵀ maximises tr(R_mᵀ · Σ b_i r_iᵀ)
    U, _s, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(U @ Vt))
    Rt = U @ np.diag([1.0, 1.0, d]) @ Vt  # R_mᵀ
    return np.asarray(Rotation.from_matrix(Rt.T).as_rotvec(), float)


def fit_rest(model: SpmModel, measured_rad: F, before_deg: F, after_deg: F, lo_deg: F,
             hi_deg: F, noise_deg: float = MIN_NOISE_DEG, arc_std_deg: float = 0.0) -> RestFit:
    """θ at rest and R_m from the three legs' measured rotations (3, 3) rad (row i: leg i
    swung from rest + before_i to rest + after_i, in the IMU's frame; the steps in deg, (3,)
    for the swung leg alone or (3, 3) with where the other joints were held);
    the starts stay inside [lo, hi] (deg, the servos' limits); ``noise_deg``: the measured
    components' expected noise (1σ), the least the standard errors assume; ``arc_std_deg``:
    how far each link arc as built may be from the model's (1σ), added to the standard errors
    (the fit takes the model's arcs). SolverError when nothing explains them, or two distinct
    poses do alike."""
    measured = np.asarray(measured_rad, float)
    b0, b1 = np.radians(np.asarray(before_deg, float)), np.radians(np.asarray(after_deg, float))
    lo, hi = np.radians(lo_deg), np.radians(hi_deg)
    fk = _Fk(model)

    def residual(x: F) -> F:
        body = nudge_rotations(model, x[:3], b0, b1, fk)
        if body is None:
            return np.full(9, 1.0)  # no pose: far worse than any rotation measured
        Rm = Rotation.from_rotvec(x[3:]).as_matrix()
        return np.asarray((body @ Rm - measured).ravel(), float)  # rows: R_mᵀ b_i

    home = model.theta_home
    spread = math.radians(START_SPREAD_DEG)
    starts: list[tuple[float, F]] = []
    for offs in itertools.product((0.0, -spread, spread), repeat=3):
        th0 = np.clip(home + np.asarray(offs), lo, hi)
        body = nudge_rotations(model, th0, b0, b1, fk)
        if body is not None:
            x0 = np.concatenate([th0, _mount_for(body, measured)])
            starts.append((float(np.linalg.norm(residual(x0))), x0))
    starts.sort(key=lambda s: s[0])
    found: list[tuple[float, F, F]] = []
    for _cost, x0 in starts[:REFINED_STARTS]:
        sol = least_squares(residual, x0, bounds=(np.concatenate([lo, np.full(3, -np.pi)]),
                                                  np.concatenate([hi, np.full(3, np.pi)])),
                            x_scale=np.full(6, 0.1), xtol=1e-12, ftol=1e-12, max_nfev=MAX_NFEV)
        found.append((float(np.sqrt(np.mean(sol.fun**2))), sol.x, sol.jac))
    if not found:
        raise SolverError("no pose near home explains the nudges (no start had a pose)")
    found.sort(key=lambda f: f[0])
    rms, x, jac = found[0]
    if rms > 0.2 * float(np.abs(measured).max()):
        raise SolverError(f"no pose explains the nudges' rotations (residual "
                          f"{math.degrees(rms):.3f}° RMS)")
    others = [f[0] for f in found[1:]
              if np.degrees(np.abs(f[1][:3] - x[:3])).max() > DISTINCT_DEG]
    runner = min(others, default=math.inf)
    floor = math.radians(max(MIN_NOISE_DEG, noise_deg))
    if runner < AMBIGUOUS_FACTOR * max(rms, floor):
        raise SolverError(f"two poses explain the nudges alike (residuals "
                          f"{math.degrees(rms):.4f}° and {math.degrees(runner):.4f}° RMS)")
    sigma = max(rms * math.sqrt(9.0 / 3.0), floor)  # 9 residuals, 6 unknowns
    try:
        inv = np.linalg.inv(jac.T @ jac)
    except np.linalg.LinAlgError:
        raise SolverError("the nudges do not determine the pose at rest") from None
    cov = inv * sigma**2
    if arc_std_deg > 0.0:  # the link arcs as built are not known: their share of the error
        S = inv @ jac.T @ _arc_columns(model, x, b0, b1)
        cov = cov + S @ S.T * math.radians(arc_std_deg) ** 2
    std = np.degrees(np.sqrt(np.clip(np.diag(cov)[:3], 0.0, None)))
    th, m = np.degrees(x[:3]), np.degrees(x[3:])
    return RestFit((float(th[0]), float(th[1]), float(th[2])),
                   (float(std[0]), float(std[1]), float(std[2])),
                   (float(m[0]), float(m[1]), float(m[2])), math.degrees(rms),
                   math.degrees(runner))


#: The step of the arcs' finite differences, rad.
_ARC_STEP_RAD = 1e-5


def _arc_columns(model: SpmModel, x: F, b0: F, b1: F) -> F:
    """∂(residuals)/∂(each leg's two arcs) at the solution ``x`` (9, 6), per rad: central
    differences of the wrist with one arc changed (:func:`built_model`)."""
    g = model.geom
    a0 = np.r_[g.d_alpha1, g.d_alpha2]
    Rm = Rotation.from_rotvec(x[3:]).as_matrix()
    cols = np.zeros((9, 6))
    for k in range(6):
        ends = []
        for sgn in (1.0, -1.0):
            a = a0.copy()
            a[k] += sgn * _ARC_STEP_RAD
            body = nudge_rotations(built_model(model, a[:3], a[3:]), x[:3], b0, b1)
            if body is None:
                raise SolverError("the pose at rest has no neighbour with other link arcs")
            ends.append((body @ Rm).ravel())
        cols[:, k] = (ends[0] - ends[1]) / (2.0 * _ARC_STEP_RAD)
    return cols
