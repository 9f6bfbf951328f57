"""Static poses for the gravity identification: greedy E-optimal selection near home
(:func:`design_poses`), or I-optimal for the platform's orientation across the region the wrist
will work in (:func:`design_for_orientation`), and a short tour through them (:func:`tour`).

Candidates are θ_home + r·d for each radius r and each of the 26 directions d of the cube
{−1, 0, 1}³ \\ {0} (so every joint moves by 0 or ±r): the joint offsets grow with r. Each
candidate's rows of the identification Jacobian — per degree of the free parameters, over the
noise: unlike the fit's rule it is not scaled by the prior spreads, since a design aims at the
worst standard error in degrees — are computed once at the prior through the unique FK of (4)
and the implicit derivatives of (11), (12). Poses are then added one at a time:
while the information matrix Σ Js_kᵀ Js_k is singular, the candidate that most increases
log det(M + εI) (D-optimal, regularized); once it is regular, the one that most increases its
smallest eigenvalue (E-optimal: the smallest singular value of Js, whose inverse is the largest
standard error along any direction, deg). The caller's ``is_allowed(θ_deg)`` (e.g. the certified
workspace's check) keeps the core free of any profile or workspace.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.core.commissioning.gravity import AsBuilt, evaluate, orientation_jacobian
from spm_console.core.commissioning.observability import DEFAULT_NOISE_DEG, free_basis
from spm_console.core.kinematics.model import SpmModel
from spm_console.errors import BadInputError, SolverError

F = NDArray[np.float64]

DIRECTIONS: F = np.array([d for d in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(d)])
"""The 26 joint-offset directions of the candidates (every joint 0 or ±1)."""
D_REGULARIZATION = 1e-6
"""ε of the D-optimal phase, relative to the largest diagonal entry of the candidates'
information."""


@dataclass(frozen=True)
class PoseDesign:
    """A proposed set of static poses (degrees)."""

    theta_deg: tuple[tuple[float, float, float], ...]
    """The poses to command, in the order chosen (home first when included)."""
    singular_values: tuple[float, ...]
    """Singular values of the scaled Jacobian of these poses at the prior, 1/deg, largest first."""
    worst_std_deg: float
    """1/σ_min: the largest standard error along any direction at the stated noise, deg."""
    candidates: int
    """Candidate poses considered."""
    refused: int
    """Candidates ``is_allowed`` refused."""
    unreachable: int
    """Candidates without a unique FK at the prior."""
    orientation_std_deg: float | None = None
    """The largest predicted standard error of the platform's orientation over the reference
    poses (the worst direction), deg, at the stated noise (None: not a design for it)."""


def candidate_poses(theta_home_deg: F, radii_deg: tuple[float, ...]) -> F:
    """θ_home + r·d for every radius and each of :data:`DIRECTIONS` ((26·len(radii), 3), deg)."""
    home = np.asarray(theta_home_deg, float).reshape(3)
    return np.asarray([home + r * d for r in radii_deg for d in DIRECTIONS])


def design_poses(
    model: SpmModel,
    count: int,
    radii_deg: tuple[float, ...] = (3.0, 6.0, 10.0),
    is_allowed: Callable[[F], bool] | None = None,
    prior: AsBuilt | None = None,
    fixed: Mapping[str, float] | None = None,
    noise_deg: float = DEFAULT_NOISE_DEG,
    include_home: bool = True,
) -> PoseDesign:
    """Choose ``count`` poses (home included when ``include_home``) among
    :func:`candidate_poses` by the greedy rule of the module's docstring.

    ``is_allowed`` receives a candidate's θ as commanded (deg, (3,)) and says whether the wrist
    may go there; ``prior``: the parameters the Jacobian is taken at (default: the model's
    arcs); ``fixed``: parameters the fit will hold (they take no part in the design).
    """
    if count < 1 or not radii_deg or min(radii_deg) <= 0.0 or noise_deg <= 0.0:
        raise BadInputError("design: count ≥ 1, radii > 0 and a positive noise are needed")
    home = np.degrees(model.theta_home)
    cand = candidate_poses(home, tuple(float(r) for r in radii_deg))
    if include_home:
        cand = np.vstack([home, cand])
    allowed = np.array([bool(is_allowed(c.copy())) if is_allowed else True for c in cand])
    refused = int((~allowed).sum())
    p = (prior or AsBuilt.of_model(model)).vector_rad()
    rows, unreachable = _rows(model, p, cand[allowed], noise_deg, fixed or {})
    ok = np.isfinite(rows).all(axis=(1, 2))
    keep, blocks = np.flatnonzero(allowed)[ok], rows[ok]
    if len(blocks) == 0:
        raise BadInputError("design: no candidate pose is allowed and reachable")
    chosen = _greedy(blocks, count, first=0 if include_home and keep[0] == 0 else None)
    M = sum((blocks[i].T @ blocks[i] for i in chosen), np.zeros((blocks.shape[2],) * 2))
    sv = np.sqrt(np.clip(np.linalg.eigvalsh(M), 0.0, None))[::-1]
    worst = 1.0 / sv[-1] if len(sv) and sv[-1] > 0 else math.inf
    theta = tuple((float(t[0]), float(t[1]), float(t[2])) for t in cand[keep[chosen]])
    return PoseDesign(theta, tuple(float(s) for s in sv), float(worst), len(cand), refused,
                      unreachable)


def _rows(model: SpmModel, p: F, cand_deg: F, noise_deg: float,
          fixed: Mapping[str, float]) -> tuple[F, int]:
    """Each candidate's 3 rows of the scaled Jacobian over the free parameters (NaN where the
    FK fails), and how many failed."""
    N = free_basis(fixed)
    if len(cand_deg) == 0:
        return np.empty((0, 3, N.shape[1])), 0
    scale = (math.pi / 180.0) / math.radians(noise_deg)
    try:
        J = evaluate(model, p, np.radians(cand_deg)).jacobian
        assert J is not None
        return J @ N * scale, 0
    except SolverError:
        pass
    out = np.full((len(cand_deg), 3, N.shape[1]), np.nan)
    for k, c in enumerate(cand_deg):  # one at a time: which ones fail
        try:
            Jk = evaluate(model, p, np.radians(c[None])).jacobian
            assert Jk is not None
            out[k] = Jk[0] @ N * scale
        except SolverError:
            continue
    return out, int((~np.isfinite(out).all(axis=(1, 2))).sum())


def _greedy(blocks: F, count: int, first: int | None) -> list[int]:
    n = blocks.shape[2]
    info = np.einsum("kri,krj->kij", blocks, blocks)
    eps = D_REGULARIZATION * float(np.einsum("kii->i", info).max() or 1.0)
    chosen: list[int] = [] if first is None else [first]
    M = info[chosen].sum(axis=0) if chosen else np.zeros((n, n))
    while len(chosen) < min(count, len(blocks)):
        rest = np.setdiff1d(np.arange(len(blocks)), chosen)
        trial = M[None] + info[rest]
        lam = np.linalg.eigvalsh(trial)
        if lam[:, 0].max() > eps:  # regular: E-optimal
            best = rest[int(np.argmax(lam[:, 0]))]
        else:  # singular: D-optimal on M + εI
            best = rest[int(np.argmax(np.log(np.clip(lam, 0.0, None) + eps).sum(axis=1)))]
        chosen.append(int(best))
        M = M + info[best]
    return chosen


def design_for_orientation(
    model: SpmModel,
    count: int,
    candidates_deg: F,
    reference_deg: F,
    prior: AsBuilt | None = None,
    fixed: Mapping[str, float] | None = None,
    noise_deg: float = DEFAULT_NOISE_DEG,
) -> PoseDesign:
    """Choose ``count`` of ``candidates_deg`` (the first one always: e.g. home) that best
    predict the platform's orientation at ``reference_deg`` (poses the wrist will work at, deg).

    I-optimal: with C = (Σ Js_kᵀ Js_k + εI)⁻¹ the covariance of the free parameters and W the
    mean of J_ωᵀ J_ω over the reference poses (J_ω: the platform's rotation per parameter, from
    (4) and (11), (12)), each step adds the candidate that most lowers tr(W C), the mean squared
    orientation error the fitted wrist will predict. Near the boundary a link arc moves the
    platform most, and there gravity sees it most too: the candidates should span the region,
    not a ball around home. The caller draws them inside it (the core knows no workspace)."""
    cand = np.asarray(candidates_deg, float).reshape(-1, 3)
    ref = np.asarray(reference_deg, float).reshape(-1, 3)
    if count < 1 or len(cand) == 0 or len(ref) == 0 or noise_deg <= 0.0:
        raise BadInputError("design: count ≥ 1, candidates, reference poses and a positive "
                            "noise are needed")
    ab = prior or AsBuilt.of_model(model)
    fixed = fixed or {}
    rows, unreachable = _rows(model, ab.vector_rad(), cand, noise_deg, fixed)
    ok = np.asarray(np.isfinite(rows).all(axis=(1, 2)), bool)
    if not ok[0]:
        raise BadInputError("design: the first candidate has no unique FK at the prior")
    keep, blocks = np.flatnonzero(ok), rows[ok]
    N = free_basis(fixed)
    Jw = orientation_jacobian(model, ab, ref) @ N * (math.pi / 180.0)  # rad per deg of q
    W = np.einsum("kai,kaj->ij", Jw, Jw) / len(ref)
    info = np.einsum("kri,krj->kij", blocks, blocks)
    eps = D_REGULARIZATION * float(np.einsum("kii->i", info).max() or 1.0)
    eye = np.eye(info.shape[1])
    chosen = [0]
    M = info[0].copy()
    while len(chosen) < min(count, len(blocks)):
        rest = np.setdiff1d(np.arange(len(blocks)), chosen)
        C = np.linalg.inv(M[None] + info[rest] + eps * eye)
        best = rest[int(np.argmin(np.einsum("ij,kji->k", W, C)))]
        chosen.append(int(best))
        M = M + info[best]
    sv = np.sqrt(np.clip(np.linalg.eigvalsh(M), 0.0, None))[::-1]
    worst = 1.0 / sv[-1] if len(sv) and sv[-1] > 0 else math.inf
    C = np.linalg.pinv(M)
    per_pose = np.linalg.eigvalsh(np.einsum("kai,ij,kbj->kab", Jw, C, Jw))[:, -1]
    orient = math.degrees(math.sqrt(max(float(per_pose.max()), 0.0)))
    theta = tuple((float(t[0]), float(t[1]), float(t[2])) for t in cand[keep[chosen]])
    return PoseDesign(theta, tuple(float(s) for s in sv), float(worst), len(cand), 0,
                      unreachable, orient)


def tour(poses_deg: F, start_deg: F) -> list[int]:
    """An order of ``poses_deg`` (K, 3) that keeps the moves short: from ``start_deg``, always
    the nearest pose not yet visited (the largest joint move, deg; ties to the first)."""
    left = list(range(len(np.asarray(poses_deg).reshape(-1, 3))))
    pts = np.asarray(poses_deg, float).reshape(-1, 3)
    here = np.asarray(start_deg, float).reshape(3)
    order: list[int] = []
    while left:
        d = np.abs(pts[left] - here).max(axis=1)
        nxt = left.pop(int(np.argmin(d)))
        order.append(nxt)
        here = pts[nxt]
    return order
