"""The identification experiment: an excitation around a rest pose, and what its record says.

The excitation (:func:`excitation`) moves the three joints together about a centre pose
(joint j by sign (+, −, +)[j] of a common signal, so the platform turns about a fixed axis
rather than the legs closing on each other): steps up and down of several amplitudes held
until the servo settles, a chirp (a sine whose frequency sweeps up) and triangle ramps at
fractions of the speed bound. It comes in two parts of the same kinds with other amplitudes:
the first is fitted, the second held out to measure the model's error on data it never saw.
References only: the runtime verifies them like any plan (workspace, limits, speed, steps).

:func:`assess` compares a fitted model with the record, block by block: per block the largest
reference–position error |θ* − θ| it reached and the model's residual there. A block whose
residual RMS exceeds :data:`SATURATION_FACTOR` times the median block's reached the servo's
nonlinear range (its drive saturates); the linear range is the largest error of the blocks
below the first such one. The residual bound is the held-out part's largest |model − θ|.
Degrees, seconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from spm_console.core.servo.identify import IdentifyResult, identify, response
from spm_console.core.servo.load import LoadModel
from spm_console.core.servo.load_fit import fit_load, model_velocity
from spm_console.core.servo.model import Dynamics
from spm_console.core.servo.order import OrderCheck, check_order

F = NDArray[np.float64]

SIGNS = np.array([1.0, -1.0, 1.0])
"""Direction of each joint's excursion for a positive signal."""
HOLD_S = 0.5
"""A step is held this long, s (the MX-106 settles within about 0.15 s)."""
REST_S = 0.3
"""Back at the centre between blocks, s."""
CHIRP_HZ = (0.5, 4.0)
"""Chirp frequencies, from and to, Hz."""
SATURATION_FACTOR = 3.0
"""A block's residual RMS above this many times the median block's marks saturation."""
MAX_MOTION_S = 30.0
"""Longest excitation, s of motion."""

Part = Literal["fit", "held-out"]


@dataclass(frozen=True)
class Block:
    """One piece of the excitation: samples [first, last) of the record."""

    kind: Literal["step", "chirp", "ramp"]
    part: Part
    first: int
    last: int
    size: float
    """Step amplitude or chirp amplitude (deg), or ramp speed (deg/s)."""


@dataclass(frozen=True)
class Excitation:
    """References (N+1, 3) about ``centre_deg`` and the blocks they are made of."""

    reference_deg: F
    blocks: tuple[Block, ...]
    centre_deg: F
    step_deg: float
    """Largest step amplitude, deg."""
    speed_degps: float
    """Fastest ramp, deg/s."""
    ts: float
    """Sampling interval, s."""

    @property
    def duration_s(self) -> float:
        """Length of the motion, s."""
        return float(len(self.reference_deg) - 1) * self.ts

    def mask(self, part: Part) -> NDArray[np.bool_]:
        """Samples of one part."""
        m = np.zeros(len(self.reference_deg), bool)
        for b in self.blocks:
            if b.part == part:
                m[b.first:b.last] = True
        return m


def excitation(centre_deg: F, ts: float, step_deg: float, speed_degps: float) -> Excitation:
    """The experiment's references: ``step_deg`` > 0 is the largest step (and the chirp's and
    ramps' half-width), ``speed_degps`` > 0 the fastest reference speed of the chirp and ramps.
    The caller picks them inside what the runtime will accept (steps ≤ 10°, the model's speed
    within the profile's bound, the excursion inside the workspace)."""
    if not (step_deg > 0 and speed_degps > 0 and ts > 0):
        raise ValueError("step, speed and Ts must be positive")
    c = np.asarray(centre_deg, float).reshape(3)
    signal: list[float] = []
    blocks: list[Block] = []

    def add(kind: Literal["step", "chirp", "ramp"], part: Part, size: float, values: F) -> None:
        first = len(signal)
        signal.extend(values.tolist())
        signal.extend([0.0] * round(REST_S / ts))
        blocks.append(Block(kind, part, first, len(signal), size))

    def steps(part: Part, fractions: tuple[float, ...]) -> None:
        for f in fractions:
            for sign in (1.0, -1.0):
                a = sign * f * step_deg
                add("step", part, abs(a), np.full(round(HOLD_S / ts), a))

    def chirp(part: Part, fraction: float, seconds: float) -> None:
        n = round(seconds / ts)
        t = np.arange(n) * ts
        f0, f1 = CHIRP_HZ
        f = f0 + (f1 - f0) * t / seconds
        phase = 2 * math.pi * (f0 * t + (f1 - f0) * t * t / (2 * seconds))
        amp = np.minimum(fraction * step_deg, 0.8 * speed_degps / (2 * math.pi * f))
        add("chirp", part, fraction * step_deg, amp * np.sin(phase))

    def ramp(part: Part, fraction: float) -> None:
        v = fraction * speed_degps
        half = 0.8 * step_deg
        up = np.arange(0.0, half, v * ts)
        tri = np.concatenate([up, half - up, -up, -half + up, [0.0]])
        add("ramp", part, v, tri)

    steps("fit", (0.35, 0.7, 1.0))
    chirp("fit", 0.6, 4.0)
    ramp("fit", 0.5)
    ramp("fit", 0.9)
    steps("held-out", (0.5, 0.85))
    chirp("held-out", 0.45, 3.0)
    ramp("held-out", 0.7)
    lead = round(REST_S / ts)
    s = np.concatenate([np.zeros(lead), np.asarray(signal), np.zeros(1)])
    blocks = [Block(b.kind, b.part, b.first + lead, b.last + lead, b.size) for b in blocks]
    ref = c[None, :] + s[:, None] * SIGNS[None, :]
    return Excitation(ref, tuple(blocks), c, step_deg, speed_degps, ts)


@dataclass(frozen=True)
class BlockFit:
    """The model against one block of the record."""

    block: Block
    reached_deg: float
    """Largest |θ* − θ| measured in the block, deg."""
    rms_deg: float
    """RMS of model − measured in the block, deg."""
    max_deg: float


@dataclass(frozen=True)
class Assessment:
    """What the record says of a fitted model."""

    blocks: tuple[BlockFit, ...]
    fit_rms_deg: float
    held_out_rms_deg: float
    held_out_max_deg: float
    linear_range_deg: float
    """Largest |θ* − θ| at which the servo still followed the model, deg."""
    saturated: bool
    """True when a block went beyond it; False: the experiment never reached the servo's
    nonlinear range, and the linear range is at least what it reached."""
    model_deg: F
    """(n, 3) the model's positions at the samples, deg."""


def assess(ex: Excitation, t: F, measured_deg: F, model: Dynamics, theta0_deg: F,
           offset_deg: F | None = None) -> Assessment:
    """The model run from rest at ``theta0_deg`` under the experiment's references (less the
    load's offset (n, 3), when given), against the measured positions (n, 3) at the instants
    ``t`` (s) of its first n samples; a row whose reply was lost is NaN and left out of every
    figure."""
    ref = ex.reference_deg[: len(t)]
    if offset_deg is not None:
        ref = ref - offset_deg
    meas = np.asarray(measured_deg, float)
    seen = np.isfinite(meas).all(axis=1)
    sim = response(model, model.delay_s, np.asarray(t, float) - float(t[0]), ref,
                   np.asarray(theta0_deg, float))
    err = sim - meas
    lag = np.abs(ref - meas)
    fits = []
    for b in ex.blocks:
        ok = seen[b.first:b.last]
        e, g = err[b.first:b.last][ok], lag[b.first:b.last][ok]
        if len(e) == 0:
            continue
        fits.append(BlockFit(b, float(g.max()), float(np.sqrt(np.mean(e * e))),
                             float(np.abs(e).max())))
    median = float(np.median([f.rms_deg for f in fits])) if fits else 0.0
    order = sorted(fits, key=lambda f: f.reached_deg)
    linear, saturated = 0.0, False
    for f in order:
        if f.rms_deg > SATURATION_FACTOR * max(median, 1e-6):
            saturated = True
            break
        linear = max(linear, f.reached_deg)
    fit_m, held = ex.mask("fit")[: len(t)] & seen, ex.mask("held-out")[: len(t)] & seen
    fe, he = err[fit_m], err[held]
    return Assessment(
        tuple(fits), float(np.sqrt(np.mean(fe * fe))) if fe.size else float("nan"),
        float(np.sqrt(np.mean(he * he))) if he.size else float("nan"),
        float(np.abs(he).max()) if he.size else float("nan"), linear, saturated, sim)


@dataclass(frozen=True)
class ExperimentFit:
    """The identified model of an experiment's record: one model for the three joints (what a
    profile holds), each joint's own fit, and what the held-out part says of it."""

    shared: IdentifyResult
    joints: tuple[IdentifyResult, ...]
    assessment: Assessment
    load: LoadModel | None = None
    """The load's offset fitted with the shared model (when the holding torques were given);
    its ``moments_deg`` holds one value: deg per N·m of holding torque."""
    order: OrderCheck | None = None
    """Whether the record asks for a third pole (:mod:`.order`); None when not checked."""

    @property
    def residual_bound_deg(self) -> float:
        """The held-out part's largest |model − θ|, rounded up to 0.01°."""
        return math.ceil(self.assessment.held_out_max_deg * 100.0 - 1e-9) / 100.0


def fit_record(ex: Excitation, t: F, reference_deg: F, measured_deg: F,
               holding_nm: F | None = None) -> ExperimentFit:
    """Fit ωn, ζ and the delay to the experiment's fit part (all joints sharing them, then
    each joint alone, driven by the reference less the shared fit's load offset), assess
    the shared model on the whole record and check whether the record asks for a third pole
    (:func:`~spm_console.core.servo.order.check_order`). ``t`` (n,) s and the
    logged references and positions (n, 3) deg of the excitation's first n samples (NaN where
    a reply was lost). With ``holding_nm`` (n, 3), the torque that holds the wrist's weight at
    the measured poses (N·m), the shared model is fitted with the load's offset
    (:func:`~spm_console.core.servo.load.fit_load`: deg per N·m of it, and Coulomb friction).
    Raises BadInputError / SolverError as :func:`identify` does."""
    t = np.asarray(t, float)
    ref, meas = np.asarray(reference_deg, float), np.asarray(measured_deg, float)
    m = ex.mask("fit")[: len(t)]
    lost = ~np.isfinite(meas[m]).all(axis=1)
    shared = identify(t[m], ref[m], meas[m], fit_delay=True, fit_damping=True, lost=lost)
    load: LoadModel | None = None
    offset: F | None = None
    if holding_nm is not None:
        hold = np.asarray(holding_nm, float)[:, :, None]
        lf = fit_load(t[m], ref[m], meas[m], hold[m], lost, shared)
        shared, load = lf.result, lf.load
        vel = model_velocity(shared.dynamics, t, ref, shared.theta0_deg)
        offset = load.offset_deg(hold, vel)
    driven = ref if offset is None else ref - offset  # what the model is driven by
    joints = tuple(identify(t[m], driven[m][:, j], meas[m][:, j], fit_delay=True,
                            fit_damping=True, lost=lost, start=shared.dynamics)
                   for j in range(ref.shape[1]))
    order = check_order(t, driven, meas, m, ex.mask("held-out")[: len(t)], shared.p,
                        shared.zeta, shared.delay_s, shared.theta0_deg)
    # the fit part starts at rest at its θ0, where the wrist rested from the record's start
    return ExperimentFit(shared, joints,
                         assess(ex, t, meas, shared.dynamics, shared.theta0_deg, offset), load,
                         order)
