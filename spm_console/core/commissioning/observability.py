"""What gravity data determine about a wrist as built: the scaled identification Jacobian, the
directions held at the prior, the imprecise ones, and the parameters held fixed.

All parameters are angles. The Jacobian J of the measured unit gravity directions (residuals
of :mod:`~spm_console.core.commissioning.gravity`, exact through (4), (11), (12)) is taken per
degree of each parameter. Scaled — each column by the parameter's prior spread (deg: how far the
wrist as built may be from the start before anything is measured), each row by the noise σ of one
component of a measured direction — it is Js = J·diag(spread)/σ, whose right singular vectors
v_k over the free parameters carry 1/σ_k: the data's standard error along v_k in prior spreads.

The rule. A direction with σ_k < :data:`HOLD_BELOW` (= 1: the data say less about it than the
prior) is *undetermined*: the fit never moves along it, so it keeps the start's (prior's) value;
holding it costs at most about σ of misfit when the prior is within its spread. A parameter whose
share in those directions (the norm of its row of their orthonormal basis, in spreads) exceeds
:data:`SHARE_TOL` is undetermined. The others are fitted; one whose standard error at the stated
noise exceeds the resolution is *imprecise* (the data move it, not to the resolution), the rest
*determined*. Named combinations (:data:`NAMED`) are checked the same way.

What gravity cannot tell apart. A pose gives two numbers (a direction). At home on a level base
a common horn offset and the mount's yaw are turns about the vertical, invisible; for the
symmetric wrist so is the common offset at every θ1 = θ2 = θ3 (the platform only yaws there).
Off that line a common offset also tilts the platform (0.14° to 0.19° per degree 10° from home),
so gravity sees it at first order in the distance from the line, like most of the rest near
home. A tilted base does not help: at home the offset turns the platform about the base's axis,
which turning the (fitted) tilt's azimuth, or the mount's yaw, mimics exactly. Each leg's horn
offset and two arcs enter only through that leg's f_i of (4): at every pose they turn the
platform along the same J1⁻¹ e_i (11), weighted by J2_ii(θ) (12), ∂f_i/∂α1_i(θ) and sin α2_i,
and the arcs' shift of the home pose is a constant turn the mount absorbs; only the change of
those weights from pose to pose separates them (the arcs at second order in the distance from
home). Near home, mixtures of arcs, horns and mount are held unless the arcs are known; poses
20° to 30° out determine all.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.core.commissioning.gravity import PARAMETERS, AsBuilt
from spm_console.errors import BadInputError

F = NDArray[np.float64]
N_P = len(PARAMETERS)

DEFAULT_NOISE_DEG = 0.03
"""σ of each component of one pose's measured gravity direction, deg. The BNO055's accelerometer
(about 0.01 m/s² per axis per sample, 150 µg/√Hz) gives 0.058° per sample, 0.006° averaged over
1 s at 100 Hz; the encoders' tick (0.088°, σ = 0.025° per joint) moves the platform by about as
much again, so the true poses scatter by more than the sensor's noise."""
DEFAULT_RESOLUTION_DEG = 0.1
"""Largest standard error (at the stated noise) of a parameter called determined, deg."""
DEFAULT_SPREAD = AsBuilt(horn_deg=(15.0, 15.0, 15.0), mount_rpy_deg=(10.0, 10.0, 10.0),
                         tilt_deg=(3.0, 3.0), d_alpha1_deg=(0.5, 0.5, 0.5),
                         d_alpha2_deg=(0.5, 0.5, 0.5))
"""Prior spreads, deg: a horn a spline tooth off (over 10° on the MX series), an IMU glued by
eye, a bench within 3° of level, printed arcs within half a degree."""
HOLD_BELOW = 1.0
"""Scaled singular value below which a direction is held at the prior."""
SHARE_TOL = 0.01
"""Largest share of a fitted parameter in the held directions: its value moves by at most this
fraction of the prior's error along them."""

COMBINATIONS: dict[str, F] = {
    "horn_common": np.r_[np.full(3, 1.0 / 3.0), np.zeros(N_P - 3)],
}
"""Linear combinations ``fixed`` may hold besides single parameters: ``horn_common`` is the mean
of the three horn offsets (a jig's reading of their common mode)."""
NAMED: dict[str, F] = {
    "common horn offset (yaw about the base axis)": COMBINATIONS["horn_common"],
    "mount yaw (about the platform axis)": np.eye(N_P)[PARAMETERS.index("mount_yaw")],
}
"""Combinations (functionals of p, deg → deg) reported by name when the data do not determine
them."""

Status = Literal["determined", "imprecise", "undetermined", "fixed"]


def constraints(fixed: Mapping[str, float]) -> tuple[F, F]:
    """(C, b) with C p = b, deg, for parameters (or :data:`COMBINATIONS`) held at values."""
    rows, vals = [], []
    for name, value in fixed.items():
        if name in COMBINATIONS:
            rows.append(COMBINATIONS[name])
        elif name in PARAMETERS:
            rows.append(np.eye(N_P)[PARAMETERS.index(name)])
        else:
            raise BadInputError(f"fixed: unknown parameter {name!r} (known: "
                                f"{', '.join((*PARAMETERS, *COMBINATIONS))})")
        if not math.isfinite(value):
            raise BadInputError(f"fixed: {name} = {value} is not a finite angle")
        vals.append(float(value))
    C = np.asarray(rows, float).reshape(-1, N_P)
    if len(C) and np.linalg.matrix_rank(C) < len(C):
        raise BadInputError(f"fixed: the held values are not independent ({', '.join(fixed)})")
    return C, np.asarray(vals, float)


def null_basis(C: F) -> F:
    """Orthonormal basis (14, n) of the vectors C maps to zero."""
    if len(C) == 0:
        return np.eye(N_P)
    _, s, Vt = np.linalg.svd(C)
    return np.asarray(Vt[int((s > 1e-12 * s[0]).sum()):].T)


def free_basis(fixed: Mapping[str, float]) -> F:
    """Orthonormal basis (14, n), per degree, of the parameter changes ``fixed`` leaves free."""
    return null_basis(constraints(fixed)[0])


def spread_of(spread: AsBuilt) -> F:
    s = np.degrees(spread.vector_rad())
    if not (np.isfinite(s).all() and (s > 0.0).all()):
        raise BadInputError("spread: every parameter's prior spread must be a positive angle")
    return s


@dataclass(frozen=True)
class Split:
    """The free parameters split by the rule, in prior-spread coordinates q = p / spread."""

    singular_values: F
    """σ_k of Js over the free parameters, descending (zeros where there are fewer rows)."""
    fitted: F
    """Orthonormal basis (14, m) of the fitted directions, q-space."""
    held: F
    """Orthonormal basis (14, h) of the held directions, q-space (weakest last)."""


def split(J_deg: F, N_q: F, spread: F, noise_deg: float) -> Split:
    """The rule on the Jacobian J_deg (rows, 14) per degree, over the free directions N_q (q)."""
    Js = J_deg * spread / math.radians(noise_deg)
    _, sv, Wt = np.linalg.svd(Js @ N_q, full_matrices=True)
    sv = np.r_[sv, np.zeros(N_q.shape[1] - len(sv))]
    keep = sv >= HOLD_BELOW
    return Split(sv, N_q @ Wt[keep].T, N_q @ Wt[~keep].T)


def covariance(J_deg: F, sp: Split, spread: F, sigma_rad: float) -> F:
    """Covariance of p (deg², 14 × 14) on the fitted subspace for residual σ (rad)."""
    B = spread[:, None] * sp.fitted
    if B.shape[1] == 0:
        return np.zeros((N_P, N_P))
    A = J_deg @ B
    return np.asarray(B @ np.linalg.pinv(A.T @ A) @ B.T * sigma_rad**2)


@dataclass(frozen=True)
class Direction:
    """A direction in parameter space (unit vector per degree over the parameters)."""

    label: str
    """A name from :data:`NAMED` when it is (nearly) that combination, else its formula."""
    weights: tuple[tuple[str, float], ...]
    """Components of magnitude ≥ 0.05, largest first (rounded)."""
    vector: tuple[float, ...]
    """The unit vector itself, in the order of :data:`PARAMETERS`."""
    std_deg: float
    """Standard error along it at the stated noise, deg (inf: held at the prior)."""


def held_share(sp: Split, spread: F, functional: F) -> float:
    """Share of a functional c·p in the held directions: 0 when the fitted ones determine it."""
    if sp.held.shape[1] == 0:
        return 0.0
    d = functional * spread  # its gradient in q-space
    n = float(np.linalg.norm(d))
    return float(np.linalg.norm(sp.held.T @ d)) / n if n > 0.0 else 0.0


def direction(v: F, std_deg: float) -> Direction:
    """Name or spell out the degree-space direction ``v``."""
    v = v / np.linalg.norm(v)
    v = v * (1.0 if v[np.argmax(np.abs(v))] >= 0.0 else -1.0)
    label = ""
    for name, c in NAMED.items():
        if abs(float(v @ c)) / float(np.linalg.norm(c)) >= 0.95:
            label = name
    order = np.argsort(-np.abs(v))
    weights = tuple((PARAMETERS[j], round(float(v[j]), 4)) for j in order if abs(v[j]) >= 0.05)
    return Direction(label or " ".join(f"{w:+.2f}·{n}" for n, w in weights), weights,
                     tuple(float(c) for c in v), std_deg)


def held_directions(sp: Split, spread: F) -> tuple[Direction, ...]:
    """The held directions, weakest first, as degree-space unit vectors."""
    return tuple(direction(spread * sp.held[:, k], math.inf)
                 for k in range(sp.held.shape[1] - 1, -1, -1))


def imprecise_directions(cov_expected: F, resolution_deg: float) -> tuple[Direction, ...]:
    """Principal directions of the expected covariance whose standard error exceeds the
    resolution, worst first."""
    lam, V = np.linalg.eigh(cov_expected)
    return tuple(direction(V[:, k], math.sqrt(lam[k]))
                 for k in np.argsort(-lam) if lam[k] > resolution_deg**2)


def undetermined_named(sp: Split, spread: F, cov_expected: F,
                       resolution_deg: float) -> tuple[str, ...]:
    """Names of :data:`NAMED` combinations held at the prior or imprecise."""
    out = []
    for name, c in NAMED.items():
        std = math.sqrt(max(float(c @ cov_expected @ c), 0.0))
        if held_share(sp, spread, c) > SHARE_TOL or std > resolution_deg:
            out.append(name)
    return tuple(out)
