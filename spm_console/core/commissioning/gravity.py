"""Gravity seen by an IMU on the platform of a wrist as built, and its exact Jacobian.

Measurement model of a static pose k (degrees at the interface, radians inside):

    θ_k = θ_meas,k + δ,     g_k = R_mountᵀ · R(θ_k; α1 + dα1, α2 + dα2)ᵀ · R_tiltᵀ · e_z

- θ_meas: what the servos report (through the profile's tick map); δ: the horn offsets, one
  per leg (the true joint angle is the reported one plus δ_i).
- R(θ; arcs): the platform's rotation from the home pose of the wrist whose leg i has the arcs
  α1 + dα1_i, α2 + dα2_i — the unique FK of (4), f_i = w_i(θ_i)·v_i − cos α2_i = 0 with w_i of
  (2) and v_i = R v_i^home, in the home assembly and working modes (continuation from home).
  R = I at θ_home: the platform frame is the base frame at home (as in the physical twin).
- R_tilt = Ry(tilt_y) · Rx(tilt_x): the base's orientation in the world (turned about the world
  x by tilt_x, then about the world y by tilt_y). Its yaw is no parameter: gravity cannot see it.
- R_mount = Rz(yaw) · Ry(pitch) · Rx(roll) (the convention of
  :func:`~spm_console.core.kinematics.rotations.rpy_matrix`): the IMU's axes in the platform
  frame (sensor → platform). Map the sensor's axes onto the platform's nominal axes first
  (the BNO055's AXIS_MAP registers) so that the mount stays far from pitch ±90°.
- e_z: the specific force at rest points up; only its direction is used (unit vectors).

Derivatives. A small rotation ω of the platform (R ← exp([ω]×) R) changes g by
R_mᵀ Rᵀ [a]× ω, a = R_tiltᵀ e_z. ω follows from (4) by implicit differentiation: with J1 (11),
J2 (12) = −∂f/∂θ and F_α = ∂f/∂α (diagonal), J1 dω = J2 dθ − F_α1 dα1 − F_α2 dα2. The arcs move
the home pose too (R is relative to it): with ω_θ, ω_h the arcs' rotations of the platform at θ
and at home, R's own is ω_θ − R ω_h.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.continuation import continuation_step
from spm_console.core.kinematics.geometry import SpmGeometry
from spm_console.core.kinematics.jacobian import j1_matrix, j2_diag
from spm_console.core.kinematics.model import SpmModel, newton, platform_axes
from spm_console.errors import BadInputError, SolverError

F = NDArray[np.float64]

PARAMETERS: tuple[str, ...] = (
    "horn1", "horn2", "horn3",
    "mount_roll", "mount_pitch", "mount_yaw",
    "tilt_x", "tilt_y",
    "d_alpha1_leg1", "d_alpha1_leg2", "d_alpha1_leg3",
    "d_alpha2_leg1", "d_alpha2_leg2", "d_alpha2_leg3",
)
"""The identified parameters p, in the order of every vector and Jacobian column here."""

_EX, _EY, _EZ = np.eye(3)


@dataclass(frozen=True)
class AsBuilt:
    """One wrist as built, in degrees: every parameter of the measurement model."""

    horn_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Horn offsets δ, deg: the true joint angle is the reported one plus δ_i."""
    mount_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """The IMU's orientation in the platform frame, roll, pitch, yaw (R = Rz·Ry·Rx), deg."""
    tilt_deg: tuple[float, float] = (0.0, 0.0)
    """The base's tilt in the world: about world x, then about world y, deg."""
    d_alpha1_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Each leg's proximal arc minus α1, deg (the geometry's d_alpha1)."""
    d_alpha2_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Each leg's distal arc minus α2, deg (the geometry's d_alpha2)."""

    def vector_rad(self) -> F:
        """p (14,), rad, in the order of :data:`PARAMETERS`."""
        return np.radians(np.concatenate([np.asarray(getattr(self, f.name), float)
                                          for f in fields(self)]))

    @classmethod
    def from_vector_rad(cls, p: F) -> AsBuilt:
        d = [float(x) for x in np.degrees(np.asarray(p, float))]
        return cls((d[0], d[1], d[2]), (d[3], d[4], d[5]), (d[6], d[7]),
                   (d[8], d[9], d[10]), (d[11], d[12], d[13]))

    @classmethod
    def of_model(cls, model: SpmModel) -> AsBuilt:
        """The prior a model carries: its geometry's per-leg arcs, everything else zero."""
        g = model.geom
        a1 = tuple(math.degrees(x) for x in g.d_alpha1)
        a2 = tuple(math.degrees(x) for x in g.d_alpha2)
        return cls(d_alpha1_deg=(a1[0], a1[1], a1[2]), d_alpha2_deg=(a2[0], a2[1], a2[2]))


def _rx(t: float) -> F:
    c, s = math.cos(t), math.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(t: float) -> F:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(t: float) -> F:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


#: Largest joint step of the continuation from the last evaluation's poses, rad.
WARM_STEP_RAD = math.radians(1.0)
#: Largest change of an arc per step of that continuation, rad.
WARM_ARC_STEP_RAD = math.radians(0.5)


def built_model(model: SpmModel, d_alpha1: F, d_alpha2: F) -> SpmModel:
    """The model of ``model``'s wrist with the per-leg arc deviations dα1, dα2 (rad, (3,)): the
    same θ_home, its home pose continued on (4) from ``model``'s (arcs changed by at most
    :data:`WARM_ARC_STEP_RAD` per Newton solve) in the same modes."""
    g = model.geom
    a0 = np.r_[g.d_alpha1, g.d_alpha2]
    da = np.r_[np.asarray(d_alpha1, float), np.asarray(d_alpha2, float)] - a0
    if not da.any():
        return model
    R, v = np.eye(3)[None], model.v_home
    n = math.ceil(float(np.abs(da).max()) / WARM_ARC_STEP_RAD)
    for k in range(1, n + 1):
        a = a0 + da * (k / n)
        geom = SpmGeometry(g.alpha1, g.alpha2, g.beta, g.gamma, g.eta,
                           (float(a[0]), float(a[1]), float(a[2])),
                           (float(a[3]), float(a[4]), float(a[5])))
        w = geom.w(model.theta_home)
        R, res = newton(geom, w[None], R, model.v_home)
        v = platform_axes(R[0], model.v_home)
        same = (np.linalg.det(j1_matrix(v, w)) * model.det_j1_sign > 0
                and bool((j2_diag(geom.u, v, w) * model.working_signs > 0).all()))
        if not (float(res[0]) < 1e-12 and same):
            raise SolverError("the wrist with these link arcs has no home pose in the home modes "
                              f"(arcs off by up to {math.degrees(float(np.abs(a).max())):.2f}°)")
    return SpmModel(geom=geom, theta_home=model.theta_home, v_home=v,
                    working_signs=model.working_signs, det_j1_sign=model.det_j1_sign)


def _poses(model: SpmModel, p: F, theta: F, warm: Evaluation | None) -> tuple[SpmModel, F]:
    """The as-built model of p and R (K, 3, 3) at the true joint angles θ (K, 3) rad, by
    predictor-corrector continuation in θ and the arcs from the last evaluation's poses (same
    rows, nearby p) where it stays in the home modes, from home for the others."""
    R = np.empty((len(theta), 3, 3))
    todo = np.ones(len(theta), bool)
    if warm is not None and warm.theta.shape == theta.shape:
        t0, d = warm.theta, theta - warm.theta
        a0, da = warm.p[8:], p[8:] - warm.p[8:]
        n = max(1, math.ceil(float(np.abs(d).max()) / WARM_STEP_RAD),
                math.ceil(float(np.abs(da).max()) / WARM_ARC_STEP_RAD))
        th, Rc, alive = t0.copy(), warm.R.copy(), np.ones(len(theta), bool)
        built = warm.built
        for k in range(1, n + 1):
            a = np.flatnonzero(alive)
            arcs = p[8:] if k == n else a0 + da * (k / n)
            built = built_model(built, arcs[:3], arcs[3:])
            th_new = t0[a] + d[a] * (k / n)
            st = continuation_step(built, th[a], Rc[a], th_new)
            ok = st.good()
            th[a[ok]], Rc[a[ok]] = th_new[ok], st.R[ok]
            alive[a[~ok]] = False
        R[alive], todo[alive] = Rc[alive], False
    else:
        built = built_model(model, p[8:11], p[11:14])
    rows = np.flatnonzero(todo)
    for row, r in zip(rows, built.track_batch(theta[rows]) if len(rows) else [], strict=True):
        if not r.ok or r.pose is None:
            raise SolverError(f"pose {row}: θ = {np.round(np.degrees(theta[row]), 3).tolist()}° "
                              f"(reported + horn offsets) has no unique FK: {r.reason}")
        R[row] = r.pose.R
    return built, R


def _theta(theta_meas_deg: F) -> F:
    t = np.asarray(theta_meas_deg, float)
    if t.ndim != 2 or t.shape[1] != 3 or not np.isfinite(t).all():
        raise BadInputError("joint angles: a (K, 3) array of finite degrees is needed, "
                            f"got shape {t.shape}")
    return np.radians(t)


@dataclass(frozen=True)
class Evaluation:
    """The model at p for K poses (radians)."""

    p: F
    """The parameters (14,)."""
    built: SpmModel
    """The as-built wrist's model (its arcs p[8:14])."""
    theta: F
    """True joint angles θ_meas + δ (K, 3)."""
    R: F
    """Platform rotations from home (K, 3, 3)."""
    gravity: F
    """Predicted unit gravity in the sensor frame (K, 3)."""
    jacobian: F | None
    """∂g/∂p (K, 3, 14), per radian of each parameter (None when not asked)."""


def evaluate(model: SpmModel, p: F, theta_meas: F, jacobian: bool = True,
             warm: Evaluation | None = None) -> Evaluation:
    """The measurement model and (optionally) its exact Jacobian at p (14,) rad for the reported
    joint angles θ_meas (K, 3) rad (see the module's docstring). ``warm``: an evaluation of the
    same poses at a nearby p, whose rotations start Newton (the unique FK is the same)."""
    p = np.asarray(p, float)
    theta = np.asarray(theta_meas, float) + p[:3]
    built, R = _poses(model, p, theta, warm)
    Rt = _ry(p[7]) @ _rx(p[6])
    Rx_m, Ry_m, Rz_m = _rx(p[3]), _ry(p[4]), _rz(p[5])
    Rm = Rz_m @ Ry_m @ Rx_m
    a = Rt.T @ _EZ
    h = np.einsum("kba,b->ka", R, a)  # Rᵀ a: gravity in the platform frame
    g = h @ Rm  # R_mᵀ h, rowwise
    if not jacobian:
        return Evaluation(p, built, theta, R, g, None)
    K = len(theta)
    J = np.empty((K, 3, 14))
    om = _omega(built, theta, R)
    # g changes by R_mᵀ Rᵀ [a]× ω for a platform rotation ω
    Ga = np.einsum("ba,kcb,cd->kad", Rm, R, _skew(a))
    J[:, :, 0:3] = Ga @ om[:, :, :3]
    J[:, :, 8:14] = Ga @ om[:, :, 3:]
    # mount: g = Rxᵀ Ryᵀ Rzᵀ h, d Rk(t)ᵀ/dt = −[e_k]× Rk(t)ᵀ
    J[:, :, 3] = -np.cross(_EX, g)
    J[:, :, 4] = -np.cross(_EY, h @ Rz_m @ Ry_m) @ Rx_m
    J[:, :, 5] = -np.cross(_EZ, h @ Rz_m) @ Ry_m @ Rx_m
    # tilt: a = Rx(tx)ᵀ Ry(ty)ᵀ e_z
    da_x = -np.cross(_EX, a)
    da_y = _rx(p[6]).T @ -np.cross(_EY, _ry(p[7]).T @ _EZ)
    RmR = np.einsum("ba,kcb->kac", Rm, R)  # R_mᵀ Rᵀ
    J[:, :, 6] = RmR @ da_x
    J[:, :, 7] = RmR @ da_y
    return Evaluation(p, built, theta, R, g, J)


def _omega(built: SpmModel, theta: F, R: F) -> F:
    """The platform's rotation ω (R ← exp([ω]×) R, base frame) per unit of (δ, dα1, dα2)
    (K, 3, 9), rad per rad, from (4) at the true θ (K, 3) and at home (R is relative to it)."""
    geom = built.geom
    w = geom.w(theta)
    v = platform_axes(R, built.v_home)
    rhs = np.zeros((len(theta), 3, 9))
    idx = np.arange(3)
    rhs[:, idx, idx] = j2_diag(geom.u, v, w)
    rhs[:, idx, 3 + idx] = -_dfd_alpha1(geom, theta, v)
    rhs[:, idx, 6 + idx] = -np.sin(geom.alpha2_legs)
    om = np.linalg.solve(j1_matrix(v, w), rhs)
    th_h = built.theta_home[None]
    vh = built.v_home[None]
    rh = np.zeros((1, 3, 6))
    rh[:, idx, idx] = -_dfd_alpha1(geom, th_h, vh)
    rh[:, idx, 3 + idx] = -np.sin(geom.alpha2_legs)
    om_h = np.linalg.solve(j1_matrix(vh, geom.w(th_h)), rh)[0]
    om[:, :, 3:] -= R @ om_h
    return np.asarray(om)


def _skew(x: F) -> F:
    return np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])


def _dfd_alpha1(geom: SpmGeometry, theta: F, v: F) -> F:
    """∂f_i/∂α1_i (K, 3): w_i = u_i cos α1_i + m_i sin α1_i from (2), m_i ⊥ u_i a unit vector."""
    _, Q, S = geom.ik_coeffs()
    a1 = geom.alpha1_legs[:, None]
    t = theta[..., None]
    msin = Q * np.cos(t) + S * np.sin(t)  # m_i sin α1_i
    dw = -geom.u * np.sin(a1) + msin * (np.cos(a1) / np.sin(a1))
    return np.asarray(np.einsum("kij,kij->ki", dw, v))


def predict_gravity(model: SpmModel, as_built: AsBuilt, theta_meas_deg: F) -> F:
    """Unit gravity in the IMU's frame (K, 3) at the reported joint angles (K, 3) deg."""
    return evaluate(model, as_built.vector_rad(), _theta(theta_meas_deg), jacobian=False).gravity


def gravity_jacobian(model: SpmModel, as_built: AsBuilt, theta_meas_deg: F) -> F:
    """∂g/∂p (K, 3, 14) per radian of each parameter (order of :data:`PARAMETERS`)."""
    J = evaluate(model, as_built.vector_rad(), _theta(theta_meas_deg)).jacobian
    assert J is not None
    return J


def platform_orientation(model: SpmModel, as_built: AsBuilt, theta_meas_deg: F) -> F:
    """The platform's rotation from home (K, 3, 3) the as-built wrist takes at the reported
    joint angles (its horn offsets and arcs; tilt and mount play no part)."""
    return evaluate(model, as_built.vector_rad(), _theta(theta_meas_deg), jacobian=False).R


def orientation_jacobian(model: SpmModel, as_built: AsBuilt, theta_meas_deg: F) -> F:
    """∂ω/∂p (K, 3, 14), rad per rad: the platform's rotation from home (base frame) per unit
    of each parameter at the reported joint angles (K, 3) deg; zero for the mounting and the
    tilt, which move no link."""
    ev = evaluate(model, as_built.vector_rad(), _theta(theta_meas_deg), jacobian=False)
    J = np.zeros((len(ev.theta), 3, 14))
    om = _omega(ev.built, ev.theta, ev.R)
    J[:, :, 0:3] = om[:, :, :3]
    J[:, :, 8:14] = om[:, :, 3:]
    return J
