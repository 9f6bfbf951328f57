"""Identification of the closed-loop servo model (27): fit p (and a pure delay) by least squares;
with ``fit_damping``, the natural frequency ωn (reported as p) and the damping ratio ζ of the
identified structure (:class:`~spm_console.core.servo.model.Dynamics`).

Data: sample instants t (s), the reference θ*(t_k) (deg) applied from t_k until the
next sample (zero-order hold, as the executor streams it), and the measured
positions θ(t_k) (deg) — a logged step response or an executed run; one column per
joint, all joints sharing p. The model starts at rest at θ0 (one per joint, fitted
too, so the quantization of the first sample does not bias p) with the input equal
to θ0 before the first sample. With a delay d the reference sent at t_k acts from
t_k + d. The response is computed exactly (matrix exponential of (27) between
events), and p, d, θ0 are fitted by scipy's least_squares from the best point of a
coarse logarithmic grid of p.

What cannot be fitted is refused rather than answered: malformed data (non-finite values,
angles beyond ±ANGLE_MAX_DEG, times not strictly increasing, sample intervals below
DT_MIN_S, a span above SPAN_MAX_S) raise BadInputError, and so do data without the
information p needs (a reference or a response that moves less than MIN_MOTION_DEG); a fit
that does not determine p (not converged, p on its search bound, the delay on its upper
bound, a fitted response that doubling p moves by less than MIN_DOUBLING_DEG, p's standard
deviation above P_REL_STD_MAX of p or not finite) raises SolverError.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.signal import lfilter

from spm_console.core.servo.model import Dynamics, Pole, dynamics, exact_coeffs
from spm_console.errors import BadInputError, SolverError

F = NDArray[np.float64]

P_BOUNDS = (0.5, 1000.0)
"""Search range of p, rad/s."""
DELAY_MAX_S = 0.25
"""Largest pure delay considered, s."""
DELAY_GRID_S = (0.0, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.15)
"""Delays (s) of the coarse grid the fit starts from."""
DIFF_STEP_P = 1e-6
"""Finite-difference step of p, relative."""
DIFF_STEP_ABS = 1e-6
"""Finite-difference step of the delay (s) and of θ0 (deg)."""
ANGLE_MAX_DEG = 3600.0
"""Largest |θ*| or |θ| accepted, deg: ten turns, beyond any joint's travel (a multi-turn
servo included), and small enough that squared residuals of 100,000 samples stay finite."""
CLOCK_MAX_S = 1e10
"""Largest |t| accepted, s: a clock since boot or the Unix epoch in seconds; at 1e10 s a
float still resolves 2 µs, a fiftieth of DT_MIN_S."""
DT_MIN_S = 1e-4
"""Shortest sample interval accepted, s: a tenth of the shortest Ts a profile accepts
(1 ms, one bus cycle of three servos)."""
SPAN_MAX_S = 86_400.0
"""Longest record accepted, s (one day; 100,000 samples at 20 ms last 33 min)."""
MIN_MOTION_DEG = 0.5
"""Least range (max − min) of θ* and of θ on one joint for p to be identified, deg: about
6 ticks of a 4096-tick encoder (0.088°), so the response stands above its ±½-tick
quantization."""
P_REL_STD_MAX = 0.5
"""Largest standard deviation of the fitted p accepted, relative to p: beyond it the
interval p ± 2σ reaches 0 and the data do not determine p."""
MIN_DOUBLING_DEG = 0.1
"""Least change of the fitted response (27) at some sample when p is doubled, deg (just
over one 0.088° encoder tick): samples that cannot tell p from 2p (a response settled
at every sample) show only that p is large, not its value."""
ZETA_BOUNDS = (0.2, 5.0)
"""Search range of the damping ratio ζ (a profile's ``servo.zeta`` range)."""
ZETA_GRID = (0.5, 0.8, 1.0, 1.5)
"""Damping ratios of the coarse grid the fit starts from."""
UNIFORM_REL = 0.1
"""Sample intervals within this fraction of their median count as uniform for the grid."""
BOUND_REL_TOL = 1e-3
"""A fitted p within this fraction of an end of P_BOUNDS (or a delay within it of
DELAY_MAX_S) is on the bound: the optimum lies outside the search range."""


@dataclass(frozen=True)
class IdentifyResult:
    """A fitted servo model."""

    p: float
    """Double closed-loop pole at −p, rad/s (with a fitted ζ: the natural frequency ωn)."""
    delay_s: float
    """Pure delay, s (0 when not fitted)."""
    theta0_deg: F
    """(J,) fitted initial rest positions, deg."""
    rms_deg: float
    """RMS of the position residuals, deg."""
    max_abs_deg: float
    """Largest absolute residual, deg."""
    p_std: float
    """Approximate standard deviation of p from the Jacobian (rad/s)."""
    samples: int
    joints: int
    fit_delay: bool
    seconds: float
    status: str
    """least_squares' message."""
    zeta: float = 1.0
    """Damping ratio ζ (1: the paper's double pole, when not fitted)."""
    zeta_std: float = 0.0
    """Approximate standard deviation of ζ (0 when not fitted)."""
    fit_damping: bool = False

    @property
    def dynamics(self) -> Dynamics:
        """The fitted continuous model."""
        return Dynamics(self.p, self.zeta, self.delay_s)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["theta0_deg"] = self.theta0_deg.tolist()
        return d


def _forward_jacobian(resid: Callable[[F], F], v: F, hi: list[float]) -> F:
    """Forward differences with absolute steps: p by 1e-6 of itself, ζ, the delay (by 1 µs)
    and each θ0 (by 1e-6°) by 1e-6. (least_squares' relative steps vanish for a delay at its bound of 0, which
    left the delay where the coarse grid put it.) A step that would cross the upper bound is
    taken backwards."""
    r0 = resid(v)
    out = np.empty((r0.size, v.size))
    for i in range(v.size):
        h = DIFF_STEP_P * max(abs(v[0]), 1.0) if i == 0 else DIFF_STEP_ABS
        if v[i] + h > hi[i]:
            h = -h
        w = v.copy()
        w[i] += h
        out[:, i] = (resid(w) - r0) / h
    return out


def _sample(k: int) -> str:
    """Default name of sample k (0-based) in messages."""
    return f"sample {k + 1}"


def _as2d(a: F, n: int, what: str, at: Callable[[int], str] = _sample) -> F:
    """(n, J) finite angles within ±ANGLE_MAX_DEG, deg (else BadInputError naming the sample)."""
    x = np.asarray(a, float)
    if x.ndim == 1:
        x = x[:, None]
    if x.ndim != 2 or x.shape[0] != n:
        raise BadInputError(f"{what}: expected {n} rows (one per sample), got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        k = int(np.argwhere(~np.isfinite(x))[0, 0])
        raise BadInputError(f"{what}: holds non-finite values (first at {at(k)})")
    far = np.argwhere(np.abs(x) > ANGLE_MAX_DEG)
    if far.size:
        k, j = (int(i) for i in far[0])
        raise BadInputError(f"{what}: {x[k, j]:.4g}° ({at(k)}, joint {j + 1}) is outside "
                            f"±{ANGLE_MAX_DEG:g}°: not an angle in degrees")
    return x


def _check_times(t: F, at: Callable[[int], str] = _sample) -> None:
    """Finite, within ±CLOCK_MAX_S, strictly increasing by at least DT_MIN_S, spanning at
    most SPAN_MAX_S (each a BadInputError naming the first offending sample)."""
    if not np.all(np.isfinite(t)) or np.abs(t).max() > CLOCK_MAX_S:
        k = int(np.argwhere(~(np.abs(t) <= CLOCK_MAX_S))[0, 0])
        raise BadInputError(f"sample times must be finite and within ±{CLOCK_MAX_S:g} s "
                            f"({at(k)}: {t[k]:.4g} s)")
    dt = np.diff(t)
    if np.any(dt <= 0):
        k = int(np.argwhere(dt <= 0)[0, 0])
        raise BadInputError(f"sample times must be finite and strictly increasing "
                            f"({at(k + 1)}: {t[k + 1]:.9g} s after {t[k]:.9g} s)")
    if dt.min() < DT_MIN_S:
        k = int(np.argmin(dt))
        raise BadInputError(f"sample interval {dt[k]:.3g} s ({at(k)} to {at(k + 1)}) is below "
                            f"{DT_MIN_S:g} s: the times are not in seconds, or not sample times")
    span = float(t[-1] - t[0])
    if span > SPAN_MAX_S:
        raise BadInputError(f"the samples span {span:.4g} s, more than {SPAN_MAX_S:g} s (a day):"
                            " the times are not in seconds, or not one record")


def _check_motion(ref: F, meas: F) -> None:
    """Some joint's reference and measured position each move by MIN_MOTION_DEG or more:
    without a step in θ* and an answer in θ, (27) leaves p undetermined (BadInputError)."""
    ref_range = np.ptp(ref, axis=0)
    meas_range = np.ptp(meas, axis=0)
    if ref_range.max() <= 0:
        raise BadInputError("the reference never moves: nothing to identify")
    moving = ref_range >= MIN_MOTION_DEG
    if not moving.any():
        raise BadInputError(f"the reference moves by {ref_range.max():.3g}° at most, less than "
                            f"the {MIN_MOTION_DEG:g}° needed (about 6 encoder ticks): "
                            "nothing to identify")
    if not (moving & (meas_range >= MIN_MOTION_DEG)).any():
        j = int(np.argmax(np.where(moving, ref_range, -1.0)))
        raise BadInputError(f"the measured position never moves by {MIN_MOTION_DEG:g}° on a "
                            f"joint whose reference does (joint {j + 1}: reference range "
                            f"{ref_range[j]:.3g}°, measured {meas_range[j]:.3g}°): the wrist "
                            "did not follow (torque off, or the wrong columns?)")


def response(p: Pole, delay_s: float, t: F, reference: F, theta0: F) -> F:
    """Positions (n, J) at the instants t of (27) (pole −p, or ωn and ζ) at rest at θ0, under
    the delayed ZOH reference."""
    n, J = reference.shape
    switch = t + delay_s
    # events: sample instants (measure) and switching instants (input change), in time order;
    # at equal times the switch acts first only if it is strictly earlier
    times = np.concatenate([t, switch])
    kinds = np.concatenate([np.zeros(n, int), np.ones(n, int)])
    idx = np.concatenate([np.arange(n), np.arange(n)])
    order = np.lexsort((-kinds, times)) if delay_s > 0 else np.lexsort((kinds, times))
    th = [float(v) for v in np.asarray(theta0, float).reshape(J)]
    om = [0.0] * J
    u = list(th)
    rows = reference.tolist()
    out: list[list[float]] = [[]] * n
    tl, kl, il = times[order].tolist(), kinds[order].tolist(), idx[order].tolist()
    tc = tl[0]
    dyn = dynamics(p)
    coeffs: dict[float, tuple[float, float, float, float, float, float]] = {}
    for te, kind, i in zip(tl, kl, il, strict=True):
        dt = te - tc
        if dt > 0:
            # a record's intervals repeat (the period, the delay's remainder): each is
            # discretised once
            k = coeffs.get(dt)
            if k is None:
                k = coeffs[dt] = exact_coeffs(dyn, dt)
            a, b, c, d, g0, g1 = k
            for j in range(J):
                th[j], om[j] = (a * th[j] + b * om[j] + g0 * u[j],
                                c * th[j] + d * om[j] + g1 * u[j])
            tc = te
        if kind == 0:
            out[i] = list(th)
        else:
            u = rows[i]
    return np.array(out, float).reshape(n, J)


def response_uniform(dyn: Dynamics, ts: float, reference: F, theta0: F) -> F:
    """:func:`response` for samples exactly ``ts`` apart (the grid's approximation of a
    record's timing): the sampled model with its delay d = m·Ts + f as a linear filter,
    θ(k+1) = Φ θ(k) + Φ(Ts−f)Γ(f) θ*(k−m−1) + Γ(Ts−f) θ*(k−m), run by scipy's ``lfilter``
    on the deviations from the rest at θ0. (n, J) positions, deg."""
    ref = np.asarray(reference, float)
    th0 = np.asarray(theta0, float).reshape(1, -1)
    m = int(dyn.delay_s // ts)
    f = dyn.delay_s - m * ts
    a, b, c, d, _, _ = exact_coeffs(dyn, ts)
    if f > 0.0:
        pa, pb, pc, pd, g0, g1 = exact_coeffs(dyn, ts - f)
        _, _, _, _, h0, h1 = exact_coeffs(dyn, f)
        b0, b1 = (g0, g1), (pa * h0 + pb * h1, pc * h0 + pd * h1)
    else:
        b0, b1 = exact_coeffs(dyn, ts)[4:], (0.0, 0.0)
    # C adj(zI − Φ) B = B[0] z + (Φ01 B[1] − Φ11 B[0]), C = [1, 0]
    c0 = b * b0[1] - d * b0[0]
    c1 = b * b1[1] - d * b1[0]
    num = [0.0, b0[0], c0 + b1[0], c1]
    den = [1.0, -(a + d), a * d - b * c]
    u = ref - th0
    if m:
        u = np.vstack([np.zeros((m, u.shape[1])), u[:-m]])
    return np.asarray(lfilter(num, den, u, axis=0) + th0, float)


def _check_determined(p: float, delay_s: float, p_std: float, doubling_deg: float) -> None:
    """A converged fit determines p: p strictly inside P_BOUNDS, the delay below DELAY_MAX_S,
    the fitted response moved by MIN_DOUBLING_DEG at some sample when p is doubled, and p's
    standard deviation finite and at most P_REL_STD_MAX·p (else SolverError)."""
    lo, hi = P_BOUNDS
    if p <= lo * (1 + BOUND_REL_TOL) or p >= hi * (1 - BOUND_REL_TOL):
        raise SolverError(f"the fit put p on its search bound ({p:.4g} rad/s, range {lo:g}.."
                          f"{hi:g}): the data do not determine p (the response is slower or "
                          "faster than the model (27) can show on these samples)")
    if delay_s >= DELAY_MAX_S * (1 - BOUND_REL_TOL):
        raise SolverError(f"the fit put the delay on its bound ({1e3 * delay_s:.4g} ms, at "
                          f"most {1e3 * DELAY_MAX_S:g} ms): the data do not determine it")
    if doubling_deg < MIN_DOUBLING_DEG:
        raise SolverError(f"the samples cannot tell p = {p:.4g} rad/s from 2p (the fitted "
                          f"response moves by {doubling_deg:.2g}° at most, less than "
                          f"{MIN_DOUBLING_DEG:g}°): it has settled at every sample, so the samples "
                          "show only that the servo is fast against their interval; record "
                          "faster")
    if not np.isfinite(p_std) or p_std > P_REL_STD_MAX * p:
        raise SolverError(f"the data do not determine p: {p:.4g} ± {p_std:.3g} rad/s (a "
                          f"standard deviation above {100 * P_REL_STD_MAX:g} % of p)")


def identify(t: F, reference: F, measured: F, fit_delay: bool = False, *,
             at: Callable[[int], str] = _sample, fit_damping: bool = False,
             lost: NDArray[np.bool_] | None = None,
             start: Dynamics | None = None) -> IdentifyResult:
    """Least-squares fit of p (and optionally a pure delay, and a damping ratio ζ with p then
    the natural frequency) to a logged response.

    t (n,) s, reference and measured (n,) or (n, J) deg. Raises BadInputError for malformed
    data or data without the motion p needs, SolverError for a fit that does not determine
    p (see the module's docstring for the thresholds). ``at(k)`` names sample k (0-based) in
    those messages, e.g. by its line in a file. ``lost`` (n,): samples whose measurement is
    missing (a lost reply; any value there is ignored) while their reference was sent.
    ``start``: a model to start the fit from instead of the coarse grid (a fit of similar
    data, e.g. the three joints together before each alone)."""
    t0 = time.perf_counter()
    tt = np.asarray(t, float).reshape(-1)
    n = tt.size
    if n < 5:
        raise BadInputError(f"identification needs at least 5 samples, got {n}")
    _check_times(tt, at)
    ref = _as2d(reference, n, "reference", at)
    miss = np.zeros(n, bool) if lost is None else np.asarray(lost, bool).reshape(n)
    if miss[0] or miss.all():
        raise BadInputError("the first sample's measurement is missing: the fit starts there")
    meas = np.asarray(measured, float).copy()
    meas[miss] = meas[0] if meas.ndim == 1 else meas[0][None, :]  # ignored below
    meas = _as2d(meas, n, "measured", at)
    seen = ~miss
    if ref.shape != meas.shape:
        raise BadInputError(f"reference {ref.shape} and measured {meas.shape} differ in shape")
    J = ref.shape[1]
    _check_motion(ref, meas[seen])

    tt = tt - tt[0]  # a log's clock may read 1e5 s: a microsecond must still move an event

    nz = 1 if fit_damping else 0
    nd = 1 if fit_delay else 0

    def unpack(v: F) -> tuple[Dynamics, F]:
        """v = [p, (ζ), (delay), θ0…] as (ωn, ζ, delay) and θ0."""
        z = float(v[1]) if fit_damping else 1.0
        d = float(v[1 + nz]) if fit_delay else 0.0
        return Dynamics(float(v[0]), z, d), v[1 + nz + nd:]

    def resid(v: F) -> F:
        dyn, th0 = unpack(v)
        return (response(dyn, dyn.delay_s, tt, ref, th0)[seen] - meas[seen]).ravel()

    def jac(v: F) -> F:
        return _forward_jacobian(resid, v, hi)

    th_init = meas[0].copy()
    best = None
    # with ζ free the grid's delays are fewer: ζ and the delay trade against each other, and
    # the least-squares step finds the delay from any of them
    delays = (DELAY_GRID_S[::2] if fit_damping else DELAY_GRID_S) if fit_delay else (0.0,)
    grid = [(p, z, d) for p in np.geomspace(2.0, 400.0, 12)
            for z in (ZETA_GRID if fit_damping else (1.0,)) for d in delays]
    if start is not None:
        grid = [(start.wn, start.zeta if fit_damping else 1.0, start.delay_s if fit_delay else 0.0)]
    dts = np.diff(tt)
    ts = float(np.median(dts))
    uniform = len(grid) > 1 and float(np.abs(dts - ts).max()) <= UNIFORM_REL * ts
    for p, z, d in grid:
        v = np.r_[p, [z] * nz, [d] * nd, th_init]
        if uniform:  # the grid only picks a start: sampled at the median interval, in C
            e = response_uniform(Dynamics(p, z, d), ts, ref, th_init)[seen] - meas[seen]
            c = float(np.sum(e ** 2))
        else:
            c = float(np.sum(resid(v) ** 2))
        if best is None or c < best[0]:
            best = (c, v)
    assert best is not None
    lo = [P_BOUNDS[0]] + [ZETA_BOUNDS[0]] * nz + [0.0] * nd + [-np.inf] * J
    hi = [P_BOUNDS[1]] + [ZETA_BOUNDS[1]] * nz + [DELAY_MAX_S] * nd + [np.inf] * J
    v0 = np.clip(best[1], np.array(lo) + 1e-9, np.array(hi) - 1e-9)
    sol = least_squares(resid, v0, jac=jac, bounds=(lo, hi), x_scale="jac",
                        xtol=1e-12, ftol=1e-12, gtol=1e-12)
    if not sol.success:
        raise SolverError(f"identification did not converge: {sol.message}")
    r = sol.fun
    dof = max(1, r.size - sol.x.size)
    s2 = float(r @ r) / dof
    try:
        cov = np.linalg.inv(sol.jac.T @ sol.jac) * s2
        p_std = float(np.sqrt(max(cov[0, 0], 0.0)))
        z_std = float(np.sqrt(max(cov[1, 1], 0.0))) if fit_damping else 0.0
    except np.linalg.LinAlgError:
        p_std = z_std = float("nan")
    dyn, th0 = unpack(sol.x)
    p_fit, z_fit, d_fit = dyn.wn, dyn.zeta, dyn.delay_s
    fitted = response(dyn, d_fit, tt, ref, th0)
    doubling = float(np.abs(response(Dynamics(2 * p_fit, z_fit), d_fit, tt, ref, th0)
                            - fitted).max())
    _check_determined(p_fit, d_fit, p_std, doubling)
    if fit_damping:
        _check_zeta(z_fit, z_std)
    return IdentifyResult(
        p=p_fit, delay_s=d_fit, theta0_deg=th0,
        rms_deg=float(np.sqrt(np.mean(r**2))), max_abs_deg=float(np.abs(r).max()),
        p_std=p_std, samples=n, joints=J, fit_delay=fit_delay,
        seconds=time.perf_counter() - t0, status=str(sol.message), zeta=z_fit, zeta_std=z_std,
        fit_damping=fit_damping)


def _check_zeta(zeta: float, zeta_std: float) -> None:
    """A fitted ζ strictly inside ZETA_BOUNDS with a finite standard deviation below
    P_REL_STD_MAX of ζ (else SolverError)."""
    lo, hi = ZETA_BOUNDS
    if zeta <= lo * (1 + BOUND_REL_TOL) or zeta >= hi * (1 - BOUND_REL_TOL):
        raise SolverError(f"the fit put the damping ratio on its bound (ζ = {zeta:.4g}, range "
                          f"{lo:g}..{hi:g}): this servo is not a second-order position servo "
                          "on these samples")
    if not np.isfinite(zeta_std) or zeta_std > P_REL_STD_MAX * zeta:
        raise SolverError(f"the data do not determine the damping ratio: ζ = {zeta:.4g} ± "
                          f"{zeta_std:.3g}")
