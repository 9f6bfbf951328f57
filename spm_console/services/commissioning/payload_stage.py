"""The payload, from the IMU stage's poses: each was held after a verified move, so the offset
between the pose commanded and the one the servos hold is the load's (:mod:`spm_console.core.
commissioning.payload`). Fitted on the stage's fit poses, checked on its held-out ones.
Statics give the payload's first moment m·c, not its mass: the commissioned profile's load
model takes m·c (``[plant] payload_moment_kgmm``) and the fitted compliance. Degrees, N·m,
kg·m."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import model_of
from spm_console.config.plant import centre_within
from spm_console.config.schema import Profile
from spm_console.core.commissioning.payload import (
    HoldingFit,
    fit_holding,
    predicted_offsets_deg,
)
from spm_console.core.kinematics.loads import gravity_regressor
from spm_console.description.weight import PLATFORM, Weight
from spm_console.motion.goals.load_offsets import load_model

F = NDArray[np.float64]


@dataclass(frozen=True)
class PayloadReport:
    fit: HoldingFit
    held_out_rms_deg: float
    """RMS of predicted − measured offsets on the held-out poses, deg."""


def _rotations(profile: Profile, theta_deg: F) -> tuple[F, F]:
    """The poses θ (deg) in radians (n, 3) and their platform rotations (n, 3, 3) (NaN where
    the FK finds no pose)."""
    model = model_of(profile)
    th = np.radians(np.asarray(theta_deg, float).reshape(-1, 3))
    R = np.empty((len(th), 3, 3))
    for i, r in enumerate(model.track_batch(th)):  # all poses march from home together
        R[i] = r.pose.R if r.ok and r.pose is not None else np.nan
    return th, R


def _loads(profile: Profile, theta_deg: F) -> tuple[F, F]:
    """The holding torque of the wrist's bodies, without a payload (n, 3) N·m, and the
    platform's regressor (n, 3, 3) at the poses θ (deg) (NaN rows where the FK finds no
    pose), under the profile's gravity (its base's tilt)."""
    th, R = _rotations(profile, theta_deg)
    weight = Weight.of(profile, payload=False)
    tw = weight.torque_nm(th, R)
    yp = gravity_regressor(weight.model, th, R, weight.up)[:, :, PLATFORM]
    return np.asarray(tw, float), np.asarray(yp, float)


def sent_at_rest(profile: Profile, commanded_deg: F) -> F:
    """What the runtime adds to each pose ``commanded_deg`` (n, 3) it holds at rest, deg: its
    load model's offset there at speed 0, k_c·τ(θ*) with the profile's whole weight (the last
    reference of a run, :mod:`spm_console.motion.goals.load_offsets`); zeros without a load
    model."""
    load = load_model(profile)  # the runtime's own rule: its offset at rest (speed 0)
    commanded = np.asarray(commanded_deg, float).reshape(-1, 3)
    if load is None:
        return np.zeros_like(commanded)
    th, R = _rotations(profile, commanded)
    hold = Weight.of(profile).torque_nm(th, R)
    return load.offset_deg(hold[:, :, None], np.zeros_like(commanded))


#: A joint commanded less than this from where it was, deg, did not move: it keeps the
#: direction it came to rest from before.
STILL_DEG = 0.05


def approach_signs(start_deg: F, commanded_deg: F) -> F:
    """The sign (n, 3) of each joint's last motion before it rested at each of the poses
    ``commanded_deg`` (n, 3), visited in turn from ``start_deg`` (3,) (0: never moved)."""
    out = np.zeros((len(commanded_deg), 3))
    last, prev = np.zeros(3), np.asarray(start_deg, float)
    for k, th in enumerate(np.asarray(commanded_deg, float)):
        step = th - prev
        last = np.where(np.abs(step) > STILL_DEG, np.sign(step), last)
        out[k], prev = last, th
    return out


def payload_from_holding(profile: Profile, commanded_deg: F, measured_deg: F,
                         held_out: NDArray[np.bool_], start_deg: F | None = None,
                         sent_deg: F | None = None) -> PayloadReport:
    """Fit the payload to the offsets θ* + d − θ (n, 3) deg at the poses not ``held_out``
    (commanded θ*, measured θ, on ``profile``'s wrist); check it on those. ``sent_deg``: d,
    what the runtime added to each commanded pose (None: ``profile``'s own load model's,
    :func:`sent_at_rest`; give it when the poses were held on another profile, as the IMU
    stage's were on the one before the fit). ``start_deg``: where the wrist was before the
    first pose (the poses visited in their order from there): the fit then takes the gear
    friction's offset against each joint's approach. ValueError when the data do not
    determine it.

    With what was sent added back the offsets are the whole load's, k·τ: the first moment
    fitted is the whole payload's and the compliance k the drive's, whatever load model the
    poses were held with."""
    commanded = np.asarray(commanded_deg, float)
    measured = np.asarray(measured_deg, float)
    sent = sent_at_rest(profile, commanded) if sent_deg is None else np.asarray(sent_deg, float)
    offsets = commanded + sent - measured
    tw, yp = _loads(profile, measured)
    sg = None if start_deg is None else approach_signs(start_deg, commanded_deg)
    fit = fit_holding(offsets[~held_out], tw[~held_out], yp[~held_out], 0.0,
                      None if sg is None else sg[~held_out])
    pred = predicted_offsets_deg(fit, tw[held_out], yp[held_out], 0.0,
                                 None if sg is None else sg[held_out])
    rms = float(np.sqrt(np.mean((pred - offsets[held_out]) ** 2))) if held_out.any() else 0.0
    return PayloadReport(fit, rms)


#: A first moment is written when its norm is at least this many times its standard error's
#: (the fit sees a payload); below, the profile keeps its own (none: the bodies alone).
PAYLOAD_SIGNIFICANCE = 3.0
#: A compliance is written when its standard error is at most this share of it.
COMPLIANCE_REL_STD_MAX = 0.1
#: Friction's offset at rest above which the commissioned profile settles at its goals, deg
#: (half an MX-106 encoder tick: the drive rests a tick or more off its goal), and for how
#: long at most, s.
SETTLE_FRICTION_DEG = 0.044
SETTLE_S = 2.0
#: The tolerance that settling then ends at, deg: half an MX-106 tick and a little, so the
#: reading settles on the goal's nearest tick (the default 0.1° accepts a tick off: near the
#: paper's goal, 0.1° on joint 3 turns the platform by 0.26°).
SETTLE_TOLERANCE_DEG = 0.05


def payload_seen(report: PayloadReport) -> bool:
    """Whether the fit determines a payload (:data:`PAYLOAD_SIGNIFICANCE`)."""
    f = report.fit
    return bool(np.linalg.norm(f.first_moment_kgm)
                >= PAYLOAD_SIGNIFICANCE * np.linalg.norm(f.first_moment_std_kgm))


def compliance_known(report: PayloadReport) -> bool:
    """Whether the fit determines the drive's compliance (:data:`COMPLIANCE_REL_STD_MAX`)."""
    f = report.fit
    return f.compliance_std <= COMPLIANCE_REL_STD_MAX * f.compliance_deg_per_nm


def friction_seen(report: PayloadReport) -> bool:
    """Whether the fit finds the drives resting half an encoder tick or more from their goals,
    short of them or past them, by the direction they came from (:data:`SETTLE_FRICTION_DEG`;
    the gear's friction and play): what settling takes up."""
    f = report.fit.friction_deg
    return f is not None and abs(f) >= SETTLE_FRICTION_DEG


def places_payload(moment_kgmm: Sequence[float], mass_kg: float) -> bool:
    """Whether a payload of ``mass_kg`` with first moment ``moment_kgmm`` sits where a profile
    may place it (:func:`~spm_console.config.plant.centre_within`: a lighter mass than
    weighed, or a wrong first moment, puts it beyond)."""
    return centre_within(moment_kgmm, mass_kg)


def with_load_model(profile: Profile, report: PayloadReport,
                    payload_kg: float | None = None) -> Profile:
    """``profile`` with the load model the fit determines: ``[plant] payload_moment_kgmm``
    (kg·mm, 0.1) when a payload is seen, ``[servo] load_deg_per_nm`` (0.0001) when the
    compliance is known, and settling at the goal's nearest tick (``[settle] duration_s``
    :data:`SETTLE_S`, ``tolerance_deg`` :data:`SETTLE_TOLERANCE_DEG`) when the friction
    leaves the drives off their goals and the profile does not settle; with ``payload_kg``
    (weighed), ``[plant] payload_kg`` beside the first moment (the payload then sits at
    m·c / m) where that centre is one a profile may hold (:func:`places_payload`; else the
    mass is left out, unknown); what is not determined is kept as the profile has it."""
    plant, servo, settle = profile.plant, profile.servo, profile.settle
    if payload_seen(report):
        moment = tuple(round(float(x) * 1e3, 1) for x in report.fit.first_moment_kgm)
        mass = payload_kg or plant.payload_kg
        plant = plant.model_copy(update={
            "payload_moment_kgmm": moment,
            "payload_kg": mass if mass is not None and places_payload(moment, mass) else None})
    if compliance_known(report):
        servo = servo.model_copy(update={
            "load_deg_per_nm": round(report.fit.compliance_deg_per_nm, 4)})
    if friction_seen(report) and settle.duration_s == 0.0:
        settle = settle.model_copy(update={"duration_s": SETTLE_S,
                                           "tolerance_deg": SETTLE_TOLERANCE_DEG})
    return profile.model_copy(update={"plant": plant, "servo": servo, "settle": settle})
