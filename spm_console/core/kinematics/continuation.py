"""One predictor-corrector continuation step of the unique FK, vectorized over rows.

The step of :mod:`spm_console.core.kinematics.model` (predict with J1 ω = J2 dθ, correct by Newton
on (4) over rotations, orthonormalize, check the modes and ζ) written per component: every
vector is three (n,) arrays and every 3×3 matrix nine, so each operation is one numpy call
over all rows instead of a batched call over tiny matrices (about ten times fewer
instructions per row). 3×3 systems are solved by Cramer's rule and rotations are
orthonormalized by one Newton–Schulz step (their drift from orthogonality is at rounding
level, where that step equals the polar factor); results agree with the matrix form to
rounding. Radians.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.geometry import SpmGeometry


class ModeledSpm(Protocol):
    """What the step needs of a model (:class:`spm_console.core.kinematics.model.SpmModel`): the
    geometry, the base axes u, v at home and the home assembly and working mode signs."""

    @property
    def geom(self) -> SpmGeometry: ...

    @property
    def u(self) -> F: ...

    @property
    def v_home(self) -> F: ...

    @property
    def det_j1_sign(self) -> float: ...

    @property
    def working_signs(self) -> F: ...

F = NDArray[np.float64]
B = NDArray[np.bool_]
Vec = list[F]
"""Three (n,) arrays: x, y, z."""
Mat = list[list[F]]
"""Nine (n,) arrays: M[row][col]."""

#: Residual below which Newton stops (max |w·v − cos α2|).
NEWTON_TOL = 1e-14
#: Newton iterations per step, at most.
NEWTON_ITERS = 12
#: Smallest ζ tolerated along a continuation path.
PATH_ZETA_FLOOR = 1e-3


@dataclass(frozen=True)
class Step:
    """One predictor-corrector continuation step, vectorized over rows."""

    R: F
    """Corrected rotations (n, 3, 3), orthonormalized (identity where not finite)."""
    residual: F
    """Max |f| after Newton (n,)."""
    correction: F
    """‖R_corrected − R_predicted‖_F (n,): large means the corrector jumped."""
    zeta: F
    """ζ at the new pose (n,)."""
    det_side: F
    """det J1 times its home sign (n,): positive = same assembly mode."""
    leg_sides: F
    """J2 diagonal times the home signs (n, 3): positive = same working modes."""

    @property
    def converged(self) -> B:
        return np.asarray(np.isfinite(self.residual) & (self.residual <= 1e-10)
                          & (self.correction <= 0.05))

    def good(self, zeta_floor: float = PATH_ZETA_FLOOR) -> B:
        """Converged, in the home modes, and ζ ≥ ``zeta_floor``."""
        return np.asarray(self.converged & (self.det_side > 0) & (self.leg_sides > 0).all(-1)
                          & (self.zeta >= zeta_floor))


def _dot(a: Vec, b: Vec) -> F:
    return np.asarray(a[0] * b[0] + a[1] * b[1] + a[2] * b[2])


def _cross(a: Vec, b: Vec) -> Vec:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _matmul(X: Mat, Y: Mat) -> Mat:
    return [[X[i][0] * Y[0][j] + X[i][1] * Y[1][j] + X[i][2] * Y[2][j] for j in range(3)]
            for i in range(3)]


def _adjugate(rows: list[Vec]) -> tuple[list[Vec], F]:
    """(columns of adj(M), det M) of the matrix with these rows."""
    cols = [_cross(rows[1], rows[2]), _cross(rows[2], rows[0]), _cross(rows[0], rows[1])]
    return cols, _dot(rows[0], cols[0])


def _solve(rows: list[Vec], r: Vec) -> Vec:
    """x with rows·x = r (Cramer); 0 where the system is singular or not finite."""
    cols, det = _adjugate(rows)
    return _solve_adj(cols, det, r)


def _solve_adj(cols: list[Vec], det: F, r: Vec) -> Vec:
    c0, c1, c2 = cols
    with np.errstate(all="ignore"):
        x = [(c0[k] * r[0] + c1[k] * r[1] + c2[k] * r[2]) / det for k in range(3)]
    return [np.where(np.isfinite(xk), xk, 0.0) for xk in x]


def _expm(w: Vec) -> Mat:
    """Rodrigues: exp([w]×) = I + a [w]× + b [w]×², [w]×² = w wᵀ − |w|² I."""
    t2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    th = np.sqrt(t2)
    small = th < 1e-8
    ths = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - t2 / 6.0, np.sin(ths) / ths)
    b = np.where(small, 0.5 - t2 / 24.0, (1.0 - np.cos(ths)) / (ths * ths))
    bw = [b * w[0], b * w[1], b * w[2]]
    aw = [a * w[0], a * w[1], a * w[2]]
    d = 1.0 - b * t2
    return [
        [d + bw[0] * w[0], bw[0] * w[1] - aw[2], bw[0] * w[2] + aw[1]],
        [bw[1] * w[0] + aw[2], d + bw[1] * w[1], bw[1] * w[2] - aw[0]],
        [bw[2] * w[0] - aw[1], bw[2] * w[1] + aw[0], d + bw[2] * w[2]],
    ]


@dataclass(frozen=True)
class Local:
    """What a pose's mode check computes and the next predictor needs (component arrays):
    w(θ), the rows of J1, the columns of adj(J1), det J1 and the diagonal of J2."""

    w: list[Vec]
    cols: list[Vec]
    det: F
    j2: Vec

    def take(self, idx: NDArray[np.int64]) -> Local:
        """The rows ``idx``."""
        return Local([[x[idx] for x in v] for v in self.w], [[x[idx] for x in v] for v in self.cols],
                     self.det[idx], [x[idx] for x in self.j2])


@dataclass(frozen=True, slots=True)
class KernelStep:
    """One step of :meth:`Kernel.step` as component arrays (the form of :class:`Step` the
    vectorized checks use without stacking)."""

    R: Mat
    """Corrected rotations, orthonormalized (identity where not finite)."""
    residual: F
    """Max |f| after Newton (n,)."""
    correction: F
    """‖R_corrected − R_predicted‖_F (n,)."""
    zeta: F
    """ζ at the new pose (n,)."""
    det_side: F
    """det J1 times its home sign (n,): positive = same assembly mode."""
    leg_sides: Vec
    """J2 diagonal times the home signs (three (n,) arrays): positive = same working modes."""
    at: Local
    """The Jacobians at the new pose (the next step's ``at_old``)."""

    def good(self, zeta_floor: float = PATH_ZETA_FLOOR) -> B:
        """:meth:`Step.good` on component arrays: converged, in the home modes, ζ ≥
        ``zeta_floor``."""
        res, d2 = self.residual, self.leg_sides
        return np.asarray(np.isfinite(res) & (res <= 1e-10) & (self.correction <= 0.05)
                          & (self.det_side > 0) & (d2[0] > 0) & (d2[1] > 0) & (d2[2] > 0)
                          & (self.zeta >= zeta_floor))


class Kernel:
    """The constant part of the model as Python floats, and the step on component arrays."""

    def __init__(self, model: ModeledSpm) -> None:
        P, Q, S = model.geom.ik_coeffs()
        self.P, self.Q, self.S = P.tolist(), Q.tolist(), S.tolist()
        self.u = np.asarray(model.u, float).tolist()
        self.vh = np.asarray(model.v_home, float).tolist()
        self.cos_a2 = np.asarray(model.geom.cos_alpha2, float).tolist()
        self.det_sign = float(model.det_j1_sign)
        self.signs = np.asarray(model.working_signs, float).tolist()

    def w(self, th: Vec) -> list[Vec]:
        """w_i(θ_i), eq. (2): three vectors."""
        out = []
        for i in range(3):
            c, s = np.cos(th[i]), np.sin(th[i])
            P, Q, S = self.P[i], self.Q[i], self.S[i]
            out.append([P[a] + Q[a] * c + S[a] * s for a in range(3)])
        return out

    def axes(self, R: Mat) -> list[Vec]:
        """v_i = R v_i⁰: three vectors."""
        return [[R[a][0] * vh[0] + R[a][1] * vh[1] + R[a][2] * vh[2] for a in range(3)]
                for vh in self.vh]

    def j2(self, v: list[Vec], w: list[Vec]) -> Vec:
        """Diagonal of J2 (12): (u_i × w_i)·v_i."""
        out = []
        for i in range(3):
            u = self.u[i]
            uw = [u[1] * w[i][2] - u[2] * w[i][1], u[2] * w[i][0] - u[0] * w[i][2],
                  u[0] * w[i][1] - u[1] * w[i][0]]
            out.append(_dot(uw, v[i]))
        return out

    def _residual(self, v: list[Vec], w: list[Vec]) -> tuple[Vec, F]:
        f = [_dot(w[i], v[i]) - self.cos_a2[i] for i in range(3)]
        return f, np.maximum(np.maximum(np.abs(f[0]), np.abs(f[1])), np.abs(f[2]))

    def newton(self, w: list[Vec], R: Mat) -> tuple[Mat, F]:
        """Newton on (4) over rotations (R ← exp([ω]×) R) until max |f| ≤ NEWTON_TOL, at most
        NEWTON_ITERS times per row. Returns (R, max |f|)."""
        n = len(R[0][0])
        for _ in range(NEWTON_ITERS):
            v = self.axes(R)
            f, res = self._residual(v, w)
            todo = res > NEWTON_TOL
            k = np.flatnonzero(todo)
            if len(k) == 0:
                break
            sub = len(k) < n
            Rk = [[x[k] for x in row] for row in R] if sub else R
            wk = [[x[k] for x in wi] for wi in w] if sub else w
            vk = [[x[k] for x in vi] for vi in v] if sub else v
            J1 = [_cross(vk[i], wk[i]) for i in range(3)]
            om = _solve(J1, [-(fi[k] if sub else fi) for fi in f])
            Rn = _matmul(_expm(om), Rk)
            if sub:
                for a in range(3):
                    for b in range(3):
                        R[a][b] = R[a][b].copy()
                        R[a][b][k] = Rn[a][b]
            else:
                R = Rn
        return R, self._residual(self.axes(R), w)[1]

    def modes(self, w: list[Vec], R: Mat) -> tuple[F, F, Vec, Local]:
        """(ζ, det J1 · home sign, J2 diagonal · home signs, the Jacobians) at (θ, R),
        w = w(θ)."""
        v = self.axes(R)
        rows = [_cross(v[i], w[i]) for i in range(3)]
        cols, det = _adjugate(rows)
        d = self.j2(v, w)
        # ζ (jacobian.conditioning_index): |det J1| |det J2| / (‖adj(J1) J2‖ ‖adj(J2) J1‖)
        nM2 = sum(d[j] * d[j] * _dot(cols[j], cols[j]) for j in range(3))
        adj2 = [d[1] * d[2], d[0] * d[2], d[0] * d[1]]
        nMp2 = sum(adj2[i] * adj2[i] * _dot(rows[i], rows[i]) for i in range(3))
        den = np.sqrt(nM2 / 3.0) * np.sqrt(nMp2 / 3.0)
        num = np.abs(det) * np.abs(d[0] * d[1] * d[2])
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(den > 0.0, num / np.where(den > 0.0, den, 1.0), 0.0)
        z = np.clip(z, 0.0, 1.0)
        return z, det * self.det_sign, [d[i] * self.signs[i] for i in range(3)], Local(w, cols, det, d)

    def step(self, th_old: Vec, R_old: Mat, th_new: Vec, at_old: Local | None = None
             ) -> KernelStep:
        """Predict from (θ_old, R_old), correct at θ_new, as component arrays.
        ``at_old``: the Jacobians at (θ_old, R_old) when the previous step returned them
        (:attr:`KernelStep.at`)."""
        if at_old is None:
            w_old = self.w(th_old)
            v_old = self.axes(R_old)
            cols, det = _adjugate([_cross(v_old[i], w_old[i]) for i in range(3)])
            at_old = Local(w_old, cols, det, self.j2(v_old, w_old))
        rhs = [at_old.j2[i] * (th_new[i] - th_old[i]) for i in range(3)]
        om = _solve_adj(at_old.cols, at_old.det, rhs)
        Rp = _matmul(_expm(om), R_old)
        w_new = self.w(th_new)
        Rc, res = self.newton(w_new, [row[:] for row in Rp])
        corr = np.sqrt(sum((Rc[a][b] - Rp[a][b]) ** 2 for a in range(3) for b in range(3)))
        fin = np.ones(len(corr), bool)
        for row in Rc:
            for x in row:
                fin &= np.isfinite(x)
        X = [[np.where(fin, Rc[a][b], float(a == b)) for b in range(3)] for a in range(3)]
        # polar factor of a rotation off by rounding: X (3I − XᵀX) / 2
        G = [[X[0][a] * X[0][b] + X[1][a] * X[1][b] + X[2][a] * X[2][b] for b in range(3)]
             for a in range(3)]
        H = [[(3.0 * float(a == b) - G[a][b]) * 0.5 for b in range(3)] for a in range(3)]
        Rc = _matmul(X, H)
        z, d1, d2, at_new = self.modes(w_new, Rc)
        return KernelStep(Rc, res, corr, z, d1, d2, at_new)


def to_vec(x: F) -> Vec:
    """(n, 3) → three (n,) arrays (contiguous copies)."""
    return [np.ascontiguousarray(x[:, k], dtype=float) for k in range(3)]


def to_mat(R: F) -> Mat:
    """(n, 3, 3) → nine (n,) arrays."""
    return [[np.ascontiguousarray(R[:, a, b], dtype=float) for b in range(3)] for a in range(3)]


def from_mat(M: Mat) -> F:
    """Nine (n,) arrays → (n, 3, 3)."""
    return np.stack([np.stack(row, -1) for row in M], -2)


def continuation_step(model: ModeledSpm, th_old: F, R_old: F, th_new: F) -> Step:
    """Predict with J1 ω = J2 dθ from (θ_old, R_old), correct by Newton at θ_new (rad);
    rows (n, 3) and rotations (n, 3, 3)."""
    th_old = np.asarray(th_old, float).reshape(-1, 3)
    th_new = np.asarray(th_new, float).reshape(-1, 3)
    R_old = np.asarray(R_old, float).reshape(-1, 3, 3)
    st = Kernel(model).step(to_vec(th_old), to_mat(R_old), to_vec(th_new))
    return Step(from_mat(st.R), st.residual, st.correction, st.zeta, st.det_side,
                np.stack(st.leg_sides, -1))
