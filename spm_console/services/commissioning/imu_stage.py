"""Commissioning's IMU stage: once the map and a zero are known (the jig's, or the IMU's at
rest), the wrist visits a set of verified poses across the region P, the IMU measuring gravity
at each; the fit of :mod:`spm_console.core.commissioning` then refines each horn offset (after
a jig its common offset held: gravity near home hardly sees it; after a zero at rest all three
free), the IMU's mounting and the base's tilt (and each leg's arcs where the data determine
them); held-out poses verify the result.

Every move is an ordinary motion of the motion process on the zeroed profile: homed, planned
(minimum time at :data:`POSE_SPEED_DEGPS`), verified against its certified workspace, logged;
the poses lie :data:`POSE_MARGIN_DEG` inside P, or three standard errors of a zero at rest if
that is more. Degrees at the interface.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import model_of
from spm_console.config.plant import MAX_BASE_TILT_DEG
from spm_console.config.schema import Profile, Settle
from spm_console.core.commissioning.design import PoseDesign, design_for_orientation, tour
from spm_console.core.commissioning.fit import CommissioningFit, FittedParameter, fit_as_built
from spm_console.core.commissioning.observability import DEFAULT_NOISE_DEG
from spm_console.core.commissioning.verify import Verification, verify_as_built
from spm_console.core.kinematics.model import SpmModel
from spm_console.errors import BusError, SolverError
from spm_console.services.client import EstopRelay
from spm_console.services.commissioning.built_profile import with_arcs, with_tilt
from spm_console.services.commissioning.payload_stage import (
    PayloadReport,
    payload_from_holding,
    sent_at_rest,
)
from spm_console.services.session import Session
from spm_console.services.wrist_service import PoseSpec

F = NDArray[np.float64]

#: Poses the fit uses (home and the I-optimal design's), and held-out poses that verify it
#: (drawn at random among the candidates).
FIT_POSES = 24
HELD_OUT = 8
#: Candidate poses drawn inside P (with :data:`POSE_MARGIN_DEG`), and reference poses of P whose
#: platform orientation the design predicts best. 24 poses within 30° of home (E-optimal)
#: predicted the orientation over P to 0.34° (1σ, worst pose); drawn across P, to 0.05°.
CANDIDATES = 400
REFERENCE = 150
#: The draw's seed: the same profile and workspace give the same poses.
DESIGN_SEED = 38
#: Speed bound of the moves between poses, deg/s.
POSE_SPEED_DEGPS = 25.0
#: Wait at each pose before measuring, s (the platform still).
SETTLE_S = 0.4
#: Reads of the joint angles averaged at a pose, and IMU samples.
THETA_READS = 10
IMU_SAMPLES = 40
#: How well a home jig zeroes a servo, deg (one encoder tick; the twin's jig reads within
#: 0.04°): a horn offset the IMU determines to better than this moves the jig's zero
#: (:func:`_horn`), by a fraction of a tick where it must (the profile's ``tick_trim``).
JIG_ACCURACY_DEG = 360.0 / 4096
#: Largest standard error of a link arc the profile takes from the fit, deg (the arcs are
#: nominal otherwise: 0.5° off moves the platform up to 2° near the boundary).
ARC_STD_DEG = 0.25
#: Largest standard error of the base's tilt the profile takes from the fit, deg (0.1° of
#: tilt moves the load model's torques by 0.2 % of the load).
TILT_STD_DEG = 0.1
#: Largest held-out gravity-direction residual a commissioned profile may have, deg.
VERIFY_BOUND_DEG = 0.15


class GravitySource(Protocol):
    """The IMU's accelerometer: the specific force at rest in its own axes, m/s²."""

    def specific_force(self) -> F: ...


@dataclass(frozen=True)
class Refinement:
    """The IMU stage's result."""

    fit: CommissioningFit
    verification: Verification
    """On the held-out poses."""
    poses_deg: tuple[tuple[float, float, float], ...]
    """The poses visited, as commanded on the jig-zeroed profile."""
    horn_deg: tuple[float, float, float]
    """Each leg's horn offset beyond the jig's zero, deg (0 where not determined)."""
    arcs_deg: tuple[tuple[float, float, float], tuple[float, float, float]] | None
    """Each leg's proximal and distal arc offsets as fitted, deg (None: not determined to
    :data:`ARC_STD_DEG`; the profile keeps its own)."""
    motion_s: float
    """Time spent moving, s."""
    payload: PayloadReport | None = None
    """The payload's first moment from the offsets the poses were held at (None: the data
    did not determine it)."""
    tilt_deg: tuple[float, float] | None = None
    """The base's tilt as fitted (``[plant] base_tilt_deg``), deg (None: not determined to
    :data:`TILT_STD_DEG`; the profile keeps its own)."""


def refine_with_imu(profile: Profile, port: str, imu: GravitySource,
                    on_stage: Callable[[str], None],
                    stop: EstopRelay | None = None,
                    logs_root: str | Path | None = None,
                    zero_std_deg: tuple[float, float, float] | None = None) -> Refinement:
    """Visit the designed poses on ``profile`` (mapped and zeroed), fit and verify.
    ``stop``: the run's E-stop, attached to this stage's motion process; ``logs_root``: where
    its moves' run logs go (None: ``$SPM_CONSOLE_LOGS`` or ``logs/``); ``zero_std_deg``: the
    zero's standard errors when it came from the IMU at rest (None: from the jig, whose common
    offset the fit holds)."""
    model = model_of(profile)
    # the jig fixes the three horns' common offset, which gravity near home hardly sees; a
    # zero at rest leaves it to the fit (across P the Agile Wrist's gravity determines it)
    fixed = {"horn_common": 0.0} if zero_std_deg is None else None
    if stop is not None:
        stop.check()
    # the poses are held where the servos come to rest: settling would take up the offsets
    # the payload is fitted to (a profile commissioned before may settle)
    session = Session(profile.model_copy(update={"settle": Settle()}), port=port, sim=False,
                      logs_root=None if logs_root is None else Path(logs_root))
    poses: list[tuple[float, float, float]] = []
    thetas: list[F] = []
    gravity: list[F] = []
    moving = 0.0
    try:
        session.connect()
        if stop is not None:
            stop.attach(session.require_bus())
        on_stage("imu: loading the workspace the poses are verified against")
        session.wrist.load_workspace()
        margin = POSE_MARGIN_DEG if zero_std_deg is None else max(
            POSE_MARGIN_DEG, ZERO_SIGMAS * max(zero_std_deg))
        design, held_flags = _design(model, profile, session, fixed, margin)
        on_stage(f"imu: homing, then {len(design.theta_deg)} poses across the region P "
                 f"(orientation predicted to {design.orientation_std_deg or math.inf:.3f}° "
                 f"at {DEFAULT_NOISE_DEG:g}° of noise)")
        t0 = time.monotonic()
        _ok(session.home(), "homing")
        moving += time.monotonic() - t0
        for k, theta in enumerate(design.theta_deg):
            if stop is not None:  # a stop that came as the last move ended starts no other
                stop.check()
            if np.abs(np.asarray(theta) - session.read_position()).max() > 0.05:
                plan = session.plans.solve("mintime", PoseSpec("current"),
                                           PoseSpec("theta", theta), session.theta_deg,
                                           vmax_degps=POSE_SPEED_DEGPS)
                t0 = time.monotonic()
                _ok(session.execute(plan), f"the move to pose {k + 1}")
                moving += time.monotonic() - t0
            time.sleep(SETTLE_S)
            thetas.append(np.mean([session.read_position() for _ in range(THETA_READS)], axis=0))
            gravity.append(np.mean([imu.specific_force() for _ in range(IMU_SAMPLES)], axis=0))
            poses.append(theta)
            on_stage(f"imu: pose {k + 1}/{len(design.theta_deg)} θ = "
                     f"{', '.join(f'{x:.2f}' for x in thetas[-1])}°")
        if stop is not None:
            stop.check()
        plan = session.plans.solve("mintime", PoseSpec("current"), PoseSpec("home"),
                                   session.theta_deg, vmax_degps=POSE_SPEED_DEGPS)
        t0 = time.monotonic()
        _ok(session.execute(plan), "the move back home")
        moving += time.monotonic() - t0
    finally:
        if stop is not None:
            stop.detach()
        session.close()
    held = np.asarray(held_flags[:len(poses)], bool)
    th, g = np.asarray(thetas), np.asarray(gravity)
    try:
        fit = fit_as_built(model, th[~held], g[~held], fixed=fixed)
    except SolverError as exc:
        raise BusError(f"commission: the IMU fit found no wrist that explains the poses "
                       f"({exc.message}); redo the jig stage (is the IMU fixed to the "
                       "platform?). Nothing was written") from None
    check = verify_as_built(model, fit.as_built, th[held], g[held])
    on_stage(f"verify: held-out gravity residual {check.gravity_max_deg:.3f}° at most "
             f"(bound {VERIFY_BOUND_DEG:g}°), fit residual {fit.residual_rms_deg:.3f}° RMS")
    if not math.isfinite(check.gravity_max_deg) or check.gravity_max_deg > VERIFY_BOUND_DEG:
        raise BusError(f"commission: verify refused: the held-out poses' gravity is "
                       f"{check.gravity_max_deg:.3f}° from the fitted wrist's (bound "
                       f"{VERIFY_BOUND_DEG:g}°); redo the jig stage (is the wrist on its jig, "
                       "the IMU fixed to the platform?). Nothing was written")
    prior = (None,) * 3 if zero_std_deg is None else zero_std_deg
    horn = tuple(_horn(p, s) for p, s in zip(fit.parameters[:3], prior, strict=True))
    arcs = fit.parameters[8:14]
    fitted = None
    if all(_known(p, ARC_STD_DEG) for p in arcs):
        v = [p.value_deg for p in arcs]
        fitted = ((v[0], v[1], v[2]), (v[3], v[4], v[5]))
    tilt = _tilt(fit, on_stage)
    payload = None
    try:
        # the holding torques of the wrist as fitted: its joint angles with the horn offsets
        # found, its arcs, and gravity in its base's frame (3° of tilt unaccounted for leave
        # 7 % of m·c in the fit); what the runtime added to each pose is that of the profile
        # the poses were held on
        as_fitted = profile if fitted is None else with_arcs(profile, *fitted)
        as_fitted = as_fitted if tilt is None else with_tilt(as_fitted, tilt)
        delta = np.asarray(horn, float)
        commanded = np.asarray(poses, float)
        payload = payload_from_holding(as_fitted, commanded + delta, th + delta, held,
                                       np.asarray(profile.home.theta_deg, float) + delta,
                                       sent_at_rest(profile, commanded))
        s, e = payload.fit.first_moment_kgm * 1e3, payload.fit.first_moment_std_kgm * 1e3
        on_stage("payload: first moment m·c = [" + ", ".join(
            f"{x:.1f} ± {d:.1f}" for x, d in zip(s, e, strict=True)) + "] kg·mm (platform "
            f"frame), drive compliance {payload.fit.compliance_deg_per_nm:.3f} deg/(N·m), "
            + ("" if payload.fit.friction_deg is None else
               f"gear friction {payload.fit.friction_deg:.3f}°, ")
            + f"held-out offsets {payload.held_out_rms_deg:.3f}° RMS")
    except ValueError as exc:
        on_stage(f"payload: not determined ({exc})")
    return Refinement(fit, check, tuple(poses), (horn[0], horn[1], horn[2]), fitted, moving,
                      payload, tilt)


def _design(model: SpmModel, profile: Profile, session: Session,
            fixed: dict[str, float] | None,
            margin_deg: float) -> tuple[PoseDesign, list[bool]]:
    """The poses to visit in the order of a short tour from home, and which ones are held out.

    Candidates and reference poses are drawn uniformly (seeded) in the servos' range and kept
    inside the workspace's region P (the candidates with every corner of the box ±``margin_deg``
    around them: at least :data:`POSE_MARGIN_DEG`, more while the zero is uncertain): P is
    convex, so every move between two of them stays in it, and so does the wrist's true path
    while its zero is off by less than the margin."""
    region = session.wrist.ensure_workspace().region
    rng = np.random.default_rng(DESIGN_SEED)
    lo = np.array([j.min_deg for j in profile.bus.joints], float)
    hi = np.array([j.max_deg for j in profile.bus.joints], float)
    draw = rng.uniform(lo, hi, (40 * (CANDIDATES + REFERENCE), 3))
    slack = region.slack(draw)
    margin = margin_deg * np.abs(region.A).sum(axis=1)[None]
    cand = draw[(slack >= margin).all(axis=1)][:CANDIDATES + HELD_OUT]
    ref = draw[(slack >= 0.0).all(axis=1)][-REFERENCE:]
    if len(cand) < FIT_POSES + HELD_OUT or len(ref) < REFERENCE // 2:
        raise BusError("commission: the workspace's region P is too small for the IMU stage's "
                       f"poses ({len(cand)} drawn inside it {margin_deg:.2f}° from its faces)")
    home = np.degrees(model.theta_home)
    spare, held_out = cand[HELD_OUT:], cand[:HELD_OUT]
    design = design_for_orientation(model, FIT_POSES, np.vstack([home, spare]), ref,
                                    fixed=fixed)
    poses = np.vstack([np.asarray(design.theta_deg), held_out])
    order = tour(poses, home)
    fit_n = len(design.theta_deg)
    visited = tuple((float(poses[k][0]), float(poses[k][1]), float(poses[k][2])) for k in order)
    return replace(design, theta_deg=visited), [k >= fit_n for k in order]


def _tilt(fit: CommissioningFit, on_stage: Callable[[str], None]) -> tuple[float, float] | None:
    """The base's tilt the profile takes from the fit, deg: None where the fit does not know
    it to :data:`TILT_STD_DEG`, or where it is beyond what a profile may hold (said)."""
    x, y = fit.parameter("tilt_x"), fit.parameter("tilt_y")
    if not (_known(x, TILT_STD_DEG) and _known(y, TILT_STD_DEG)):
        return None
    if max(abs(x.value_deg), abs(y.value_deg)) > MAX_BASE_TILT_DEG:
        on_stage(f"base tilt ({x.value_deg:.2f}, {y.value_deg:.2f})° is beyond the "
                 f"±{MAX_BASE_TILT_DEG:g}° a profile holds: not written (the load model "
                 "keeps the profile's; level the base)")
        return None
    return (x.value_deg, y.value_deg)


def _horn(p: FittedParameter, zero_std_deg: float | None = None) -> float:
    """A horn offset beyond the zero, deg. From the jig (``zero_std_deg`` None): the fit's
    where it knows it to better than the jig (:data:`JIG_ACCURACY_DEG`), weighed against the
    jig's own zero (the nearest tick: an error uniform over one tick, variance tick²/12) by
    inverse variances; else 0. From the IMU at rest: the fit's weighed against that zero's
    standard error alike, wherever the fit knows it better."""
    ref = JIG_ACCURACY_DEG if zero_std_deg is None else zero_std_deg
    if not _known(p, ref):
        return 0.0
    assert p.std_expected_deg is not None
    prior_var = JIG_ACCURACY_DEG**2 / 12.0 if zero_std_deg is None else zero_std_deg**2
    return p.value_deg * prior_var / (prior_var + p.std_expected_deg**2)


def _known(p: FittedParameter, std_deg: float) -> bool:
    """Whether the data determine ``p`` to better than ``std_deg``."""
    return (p.status in ("determined", "imprecise") and p.std_expected_deg is not None
            and p.std_expected_deg < std_deg)


#: How far inside the certified region a pose must lie in every joint, deg: the measured
#: position at rest (tracking, the gear's play, the load) stays certified around it.
POSE_MARGIN_DEG = 2.0
#: A zero found at rest widens that margin to this many of its standard errors.
ZERO_SIGMAS = 3.0


def _ok(result: object, what: str) -> None:
    if not getattr(result, "ok", False):
        raise BusError(f"commission: {what} did not complete: "
                       f"{getattr(result, 'message', '') or 'stopped'}")
