"""One predictor-corrector continuation step of the unique FK, vectorized over rows.

The step of :mod:`spm_console.core.kinematics.model` (predict with J1 ω = J2 dθ, correct by Newton
on (4) over rotations, orthonormalize, check the modes and ζ) written per component: every
vector is three (n,) arrays and every 3×3 matrix nine, so each operation is one numpy call
over all rows instead of a batched call over tiny matrices (about ten times fewer
instructions per row). 3×3 systems are solved by Cramer's rule and rotations are
orthonormalized by one Newton–Schulz step (their drift from orthogonality is at rounding
level, where that step equals the polar factor); results agree with the matrix form to
rounding. One pose steps on Python floats instead (:class:`OneRowKernel`, the same code with
the operations of :mod:`~spm_console.core.kinematics.component_ops`): numpy's cost per call
would dominate its few hundred operations. Radians.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from spm_console.core.kinematics.component_ops import ARRAY_OPS, FLOAT_OPS, C, Mat, Ops, Vec, as_array
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

#: Residual below which Newton stops (max |w·v − cos α2|).
NEWTON_TOL = 1e-14
#: Newton iterations per step, at most.
NEWTON_ITERS = 12
#: Smallest ζ tolerated along a continuation path.
PATH_ZETA_FLOOR = 1e-3
#: A step converged: max |f| after Newton at most this, and the corrector moved R at most
#: :data:`MAX_CORRECTION` (Frobenius) from the prediction (more means it jumped).
CONVERGED_RESIDUAL = 1e-10
MAX_CORRECTION = 0.05


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
        return np.asarray(np.isfinite(self.residual) & (self.residual <= CONVERGED_RESIDUAL)
                          & (self.correction <= MAX_CORRECTION))

    def good(self, zeta_floor: float = PATH_ZETA_FLOOR) -> B:
        """Converged, in the home modes, and ζ ≥ ``zeta_floor``."""
        return np.asarray(self.converged & (self.det_side > 0) & (self.leg_sides > 0).all(-1)
                          & (self.zeta >= zeta_floor))


def _rows(x: C, idx: NDArray[np.int64]) -> C:
    """The rows ``idx`` of one component array."""
    return as_array(x)[idx]


def _dot(a: Vec, b: Vec) -> C:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: Vec, b: Vec) -> list[C]:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _matmul(X: Mat, Y: Mat) -> list[list[C]]:
    return [[X[i][0] * Y[0][j] + X[i][1] * Y[1][j] + X[i][2] * Y[2][j] for j in range(3)]
            for i in range(3)]


def _adjugate(rows: Sequence[Vec]) -> tuple[Sequence[Vec], C]:
    """(columns of adj(M), det M) of the matrix with these rows."""
    cols = [_cross(rows[1], rows[2]), _cross(rows[2], rows[0]), _cross(rows[0], rows[1])]
    return cols, _dot(rows[0], cols[0])


def _solve(rows: Sequence[Vec], r: Vec, ops: Ops) -> Vec:
    """x with rows·x = r (Cramer); 0 where the system is singular or not finite."""
    cols, det = _adjugate(rows)
    return _solve_adj(cols, det, r, ops)


def _solve_adj(cols: Sequence[Vec], det: C, r: Vec, ops: Ops) -> Vec:
    c0, c1, c2 = cols
    return [ops.div0(c0[k] * r[0] + c1[k] * r[1] + c2[k] * r[2], det) for k in range(3)]


def _expm(w: Vec, ops: Ops) -> list[list[C]]:
    """Rodrigues: exp([w]×) = I + a [w]× + b [w]×², [w]×² = w wᵀ − |w|² I."""
    t2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    a, b = ops.expm_coeffs(t2)
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

    w: Sequence[Vec]
    cols: Sequence[Vec]
    det: C
    j2: Vec

    def take(self, idx: NDArray[np.int64]) -> Local:
        """The rows ``idx``."""
        return Local([[_rows(x, idx) for x in v] for v in self.w],
                     [[_rows(x, idx) for x in v] for v in self.cols], _rows(self.det, idx),
                     [_rows(x, idx) for x in self.j2])


@dataclass(frozen=True, slots=True)
class KernelStep:
    """One step of :meth:`Kernel.step` as component arrays (the form of :class:`Step` the
    vectorized checks use without stacking)."""

    R: Mat
    """Corrected rotations, orthonormalized (identity where not finite)."""
    residual: C
    """Max |f| after Newton (n,)."""
    correction: C
    """‖R_corrected − R_predicted‖_F (n,)."""
    zeta: C
    """ζ at the new pose (n,)."""
    det_side: C
    """det J1 times its home sign (n,): positive = same assembly mode."""
    leg_sides: Vec
    """J2 diagonal times the home signs (three (n,) arrays): positive = same working modes."""
    at: Local
    """The Jacobians at the new pose (the next step's ``at_old``)."""

    def good(self, zeta_floor: float = PATH_ZETA_FLOOR) -> B:
        """:meth:`Step.good` on component arrays: converged, in the home modes, ζ ≥
        ``zeta_floor``."""
        res, d2 = self.residual, self.leg_sides
        return np.asarray(np.isfinite(res) & (res <= CONVERGED_RESIDUAL)
                          & (self.correction <= MAX_CORRECTION)
                          & (self.det_side > 0) & (d2[0] > 0) & (d2[1] > 0) & (d2[2] > 0)
                          & (self.zeta >= zeta_floor))


class Kernel:
    """The constant part of the model as Python floats, and the step on component arrays
    (:class:`OneRowKernel`: on floats, for one pose)."""

    ops: Ops = ARRAY_OPS

    def __init__(self, model: ModeledSpm) -> None:
        P, Q, S = model.geom.ik_coeffs()
        self.P, self.Q, self.S = P.tolist(), Q.tolist(), S.tolist()
        self.u = np.asarray(model.u, float).tolist()
        self.vh = np.asarray(model.v_home, float).tolist()
        self.cos_a2 = np.asarray(model.geom.cos_alpha2, float).tolist()
        self.det_sign = float(model.det_j1_sign)
        self.signs = np.asarray(model.working_signs, float).tolist()

    def w(self, th: Vec) -> Sequence[Vec]:
        """w_i(θ_i), eq. (2): three vectors."""
        out: list[Vec] = []
        for i in range(3):
            c, s = self.ops.cos_sin(th[i])
            P, Q, S = self.P[i], self.Q[i], self.S[i]
            out.append([P[a] + Q[a] * c + S[a] * s for a in range(3)])
        return out

    def axes(self, R: Mat) -> Sequence[Vec]:
        """v_i = R v_i⁰: three vectors."""
        return [[R[a][0] * vh[0] + R[a][1] * vh[1] + R[a][2] * vh[2] for a in range(3)]
                for vh in self.vh]

    def j2(self, v: Sequence[Vec], w: Sequence[Vec]) -> Vec:
        """Diagonal of J2 (12): (u_i × w_i)·v_i."""
        out = []
        for i in range(3):
            u = self.u[i]
            uw = [u[1] * w[i][2] - u[2] * w[i][1], u[2] * w[i][0] - u[0] * w[i][2],
                  u[0] * w[i][1] - u[1] * w[i][0]]
            out.append(_dot(uw, v[i]))
        return out

    def _residual(self, v: Sequence[Vec], w: Sequence[Vec]) -> tuple[Vec, C]:
        f = [_dot(w[i], v[i]) - self.cos_a2[i] for i in range(3)]
        return f, self.ops.max_abs3(f[0], f[1], f[2])

    def newton(self, w: Sequence[Vec], R: Mat) -> tuple[Mat, C]:
        """Newton on (4) over rotations (R ← exp([ω]×) R) until max |f| ≤ NEWTON_TOL, at most
        NEWTON_ITERS times per row. Returns (R, max |f|)."""
        n = len(np.asarray(R[0][0]))
        Rl = [list(row) for row in R]
        for _ in range(NEWTON_ITERS):
            v = self.axes(Rl)
            f, res = self._residual(v, w)
            k = np.flatnonzero(np.greater(res, NEWTON_TOL))
            if len(k) == 0:
                return Rl, res  # (the residual of Rl as it is returned)
            sub = len(k) < n
            Rk = [[_rows(x, k) for x in row] for row in Rl] if sub else Rl
            wk = [[_rows(x, k) for x in wi] for wi in w] if sub else w
            vk = [[_rows(x, k) for x in vi] for vi in v] if sub else v
            J1 = [_cross(vk[i], wk[i]) for i in range(3)]
            om = _solve(J1, [-(_rows(fi, k) if sub else fi) for fi in f], self.ops)
            Rn = _matmul(_expm(om, self.ops), Rk)
            if sub:
                for a in range(3):
                    for b in range(3):
                        Rab = np.array(Rl[a][b])
                        Rab[k] = Rn[a][b]
                        Rl[a][b] = Rab
            else:
                Rl = Rn
        return Rl, self._residual(self.axes(Rl), w)[1]

    def modes(self, w: Sequence[Vec], R: Mat) -> tuple[C, C, Vec, Local]:
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
        ops = self.ops
        den = ops.sqrt(nM2 / 3.0) * ops.sqrt(nMp2 / 3.0)
        num = ops.abs(det) * ops.abs(d[0] * d[1] * d[2])
        z = ops.ratio01(num, den)
        return z, det * self.det_sign, [d[i] * self.signs[i] for i in range(3)], Local(w, cols, det, d)

    def step(self, th_old: Vec, R_old: Mat, th_new: Vec, at_old: Local | None = None,
             w_new: Sequence[Vec] | None = None) -> KernelStep:
        """Predict from (θ_old, R_old), correct at θ_new, as component arrays.
        ``at_old``: the Jacobians at (θ_old, R_old) when the previous step returned them
        (:attr:`KernelStep.at`); ``w_new``: :meth:`w` of θ_new when the caller has it."""
        if at_old is None:
            w_old = self.w(th_old)
            v_old = self.axes(R_old)
            cols, det = _adjugate([_cross(v_old[i], w_old[i]) for i in range(3)])
            at_old = Local(w_old, cols, det, self.j2(v_old, w_old))
        rhs = [at_old.j2[i] * (th_new[i] - th_old[i]) for i in range(3)]
        om = _solve_adj(at_old.cols, at_old.det, rhs, self.ops)
        Rp = _matmul(_expm(om, self.ops), R_old)
        if w_new is None:
            w_new = self.w(th_new)
        Rc, res = self.newton(w_new, [row[:] for row in Rp])
        dR = [Rc[a][b] - Rp[a][b] for a in range(3) for b in range(3)]
        corr = self.ops.sqrt(sum(x * x for x in dR))
        X = self.ops.finite_or_identity(Rc)
        # polar factor of a rotation off by rounding: X (3I − XᵀX) / 2
        G = [[X[0][a] * X[0][b] + X[1][a] * X[1][b] + X[2][a] * X[2][b] for b in range(3)]
             for a in range(3)]
        H = [[(3.0 * float(a == b) - G[a][b]) * 0.5 for b in range(3)] for a in range(3)]
        Rc = _matmul(X, H)
        z, d1, d2, at_new = self.modes(w_new, Rc)
        return KernelStep(Rc, res, corr, z, d1, d2, at_new)


class OneRowKernel(Kernel):
    """:class:`Kernel` on Python floats: one pose's step without numpy's per-call cost (about
    twenty times faster than on (1,) arrays; the same arithmetic, so the same result up to
    the last bits of sin and cos)."""

    ops: Ops = FLOAT_OPS

    def newton(self, w: Sequence[Vec], R: Mat) -> tuple[Mat, C]:
        for _ in range(NEWTON_ITERS):
            v = self.axes(R)
            f, res = self._residual(v, w)
            if not res > NEWTON_TOL:  # (NaN stops too, as in the array form)
                break
            J1 = [_cross(v[i], w[i]) for i in range(3)]
            R = _matmul(_expm(_solve(J1, [-fi for fi in f], self.ops), self.ops), R)
        return R, self._residual(self.axes(R), w)[1]


_ONE_ROW: dict[int, tuple[ModeledSpm, OneRowKernel]] = {}
_ONE_ROW_LOCK = threading.Lock()


def one_row_kernel(model: ModeledSpm) -> OneRowKernel:
    """The :class:`OneRowKernel` of ``model``, kept for the last few models (building one
    costs as much as a step)."""
    with _ONE_ROW_LOCK:
        hit = _ONE_ROW.get(id(model))
        if hit is not None and hit[0] is model:
            return hit[1]
        kern = OneRowKernel(model)
        if len(_ONE_ROW) >= 8:
            del _ONE_ROW[next(iter(_ONE_ROW))]
        _ONE_ROW[id(model)] = (model, kern)  # (the model held: its id is not reused)
        return kern


def to_vec(x: F) -> list[F]:
    """(n, 3) → three (n,) arrays (contiguous copies)."""
    return [np.ascontiguousarray(x[:, k], dtype=float) for k in range(3)]


def to_mat(R: F) -> list[list[F]]:
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
    if len(th_old) == len(th_new) == len(R_old) == 1:
        one = one_row_kernel(model).step(th_old[0].tolist(), R_old[0].tolist(), th_new[0].tolist())
        return Step(np.array(one.R, float)[None], np.array([one.residual], float),
                    np.array([one.correction], float), np.array([one.zeta], float),
                    np.array([one.det_side], float), np.array([one.leg_sides], float))
    st = Kernel(model).step(to_vec(th_old), to_mat(R_old), to_vec(th_new))
    return Step(from_mat(st.R), np.asarray(st.residual, float), np.asarray(st.correction, float),
                np.asarray(st.zeta, float), np.asarray(st.det_side, float),
                np.stack(st.leg_sides, -1))
