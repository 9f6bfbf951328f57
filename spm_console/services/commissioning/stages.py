"""Commissioning a wrist as built: find its servos, map them to legs, zero them, write the
profile that matches the wrist (``spm-console commission``).

Stages, each through the motion process that owns the bus (nothing here writes to it):

1. **Discover**: scan ids 0..252 on the profile's protocol, then on the other one; refuse a
   bus without three servos of the profile's model, naming what answered.
2. **Jig** (``--jig``): the wrist rests on its home jig, torque off: each servo's ticks are
   averaged there (before anything moves; the jig is released when torque goes on).
3. **Map**: each servo alone nudged by 1.8° at 4 °/s (:mod:`~spm_console.motion.nudge`; a tick
   and its overshoot stay inside the 2° ball), the others holding; the platform rotation the
   IMU measures names its leg and the way it counts
   (:mod:`~spm_console.services.commissioning.leg_map`). Nothing else moves before the map is known.
4. **Zero** from the jig: true θ at the jig = the profile's home, so each tick offset is the
   jig's ticks less the home angle in ticks (rounded to a tick: 0.088° on the MX-106).
   Without a jig, with the IMU: each leg swings ±1.8° about its rest, and the rotations the IMU
   measures give the joint angles at rest (:mod:`~spm_console.services.commissioning.rest_zero`),
   to a few tenths of a degree; the IMU stage refines them.
5. **Write**: a profile with the found ids, directions and tick offsets, and a comment block
   of provenance; the product's profile is never overwritten.

Degrees at the interface.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from spm_console.config.models import model_of
from spm_console.config.schema import Profile
from spm_console.core.commissioning.rest import leg_axes
from spm_console.devices.imu.bno055 import Bno055, ImuSample
from spm_console.devices.imu.bno055_registers import OprMode
from spm_console.errors import BadInputError, BusError, ImuError, SpmError
from spm_console.motion.nudge import NudgeResult
from spm_console.motion.servo_query import BusQuery, BusReport, PingedServo
from spm_console.services.client import EstopRelay, MotionClient
from spm_console.services.commissioning.built_profile import validated, with_arcs, with_tilt
from spm_console.services.commissioning.imu_stage import Refinement
from spm_console.services.commissioning.leg_map import (
    ElbowMotion,
    LegMatch,
    elbow_motions,
    match_leg,
    operator_match,
    rotation_vector,
)
from spm_console.services.commissioning.payload_stage import with_load_model
from spm_console.services.commissioning.rest_zero import (
    SWING_DEG,
    RestZero,
    Swing,
    rotation_noise_deg,
    swing,
    ticks_and_trims,
    zero_at_rest,
)
from spm_console.services.session import Session

F = NDArray[np.float64]

#: The nudge of the map stage, deg of the servo's own counting, and its speed, deg/s.
MAP_NUDGE_DEG = 1.8
MAP_SPEED_DEGPS = 4.0
#: Reads averaged at the jig.
JIG_READS = 20
#: IMU samples averaged for one orientation (at the BNO055's 100 Hz: 0.2 s).
IMU_SAMPLES = 20
#: The BNO055's output period in its fusion modes, s.
IMU_PERIOD_S = 0.01
#: Model numbers of the MX-106 on protocol 2.0 and 1.0.
MX106_MODELS = {"2.0": 321, "1.0": 320}


class ImuSource(Protocol):
    """What the map stage needs of an IMU: its orientation, a unit quaternion (w, x, y, z),
    world ← sensor (a relative heading is enough: only changes are used)."""

    def quaternion(self) -> F: ...


class Bno055Source:
    """A BNO055 on ``port`` in its IMU fusion mode (accelerometer and gyroscope: a relative
    heading, no magnetometer near the servos' motors), read at its 100 Hz output rate."""

    def __init__(self, port: str, on_sample: Callable[[ImuSample], None] | None = None) -> None:
        self.on_sample = on_sample
        """Called with every reading taken (the run log's ``imu.csv``)."""
        self.device = Bno055.open(port)
        try:
            self.device.set_mode(OprMode.IMU)
        except SpmError:
            self.device.close()
            raise

    def _read(self) -> ImuSample:
        sample = self.device.read_sample()
        if self.on_sample is not None:
            self.on_sample(sample)
        time.sleep(IMU_PERIOD_S)  # the next read finds the next sample
        return sample

    def quaternion(self) -> F:
        sample = self._read()
        if sample.quat_wxyz is None:
            raise ImuError(f"the IMU on {self.device.port} gave no orientation")
        return np.asarray(sample.quat_wxyz, float)

    def specific_force(self) -> F:
        """The accelerometer's reading, m/s² (the sensor's axes)."""
        sample = self._read()
        if sample.accel_mps2 is None:
            raise ImuError(f"the IMU on {self.device.port} gave no acceleration")
        return np.asarray(sample.accel_mps2, float)

    def close(self) -> None:
        self.device.close()


@dataclass(frozen=True)
class Discovery:
    """What answered on the bus."""

    protocol: str
    found: tuple[PingedServo, ...]
    ids: tuple[int, int, int]
    """The three MX-106 ids, ascending (their legs are not known yet)."""


@dataclass(frozen=True)
class Commissioned:
    """The result: the wiring as built and where it came from."""

    discovery: Discovery
    legs: tuple[LegMatch, LegMatch, LegMatch]
    """Per leg 1..3: the servo id driving it and the way it counts."""
    jig_ticks: tuple[float, float, float] | None
    """Each leg's servo's averaged ticks at the jig (None without a jig)."""
    tick_offsets: tuple[int, int, int] | None
    """Tick offsets from the jig, or from the IMU at rest (None: neither, not zeroed)."""
    profile: Profile
    """The commissioned profile (the input's, with ``[bus]`` as built)."""
    refinement: Refinement | None = None
    """The IMU stage's fit and verification (None when it did not run)."""
    nudge_s: float = 0.0
    """Time the map stage's nudges took, s."""
    max_nudge_deg: float = 0.0
    """The farthest any servo was from its rest during the map stage, deg (at most 2°)."""
    tick_trims: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Each leg's fraction of a tick beyond its offset (−0.5..0.5): the zero at rest's, or
    the IMU stage's."""
    rest_zero: RestZero | None = None
    """The zero found at rest from the IMU (no jig), with its standard errors."""
    payload_kg_weighed: float | None = None
    """The payload's weighed mass, kg: the operator's (``--payload-kg``), else the profile's
    own ``[plant] payload_kg``; written beside the first moment when the stage determined one
    that places it (None: not known)."""
    held_at_jig: tuple[int, ...] = ()
    """The servo ids whose torque was on when the jig stage began: the wrist was held where
    it stood, maybe not on its jig (the zero is where it stood)."""


def discover(profile: Profile, port: str, on_stage: Callable[[str], None],
             stop: EstopRelay | None = None) -> tuple[Profile, Discovery]:
    """Scan the bus on the profile's protocol, then the other; the profile with the found
    protocol and ids (legs still unknown). ``stop``: the run's E-stop (see
    :class:`~spm_console.services.client.EstopRelay`)."""
    tried: list[str] = []
    for protocol in (profile.bus.protocol, "1.0" if profile.bus.protocol == "2.0" else "2.0"):
        variant = _with_bus(profile, protocol=protocol, model_number=MX106_MODELS[protocol])
        on_stage(f"discover: scanning ids 0..252 on protocol {protocol} ({port})")
        report = _scan(variant, port, stop)
        mx = [f for f in report.found if f.model_number == MX106_MODELS[protocol]]
        tried.append(f"protocol {protocol}: " + (", ".join(
            f"id {f.id} model {f.model_number}" for f in report.found) or "nothing"))
        if len(mx) == 3:
            ids = (mx[0].id, mx[1].id, mx[2].id)
            found = _with_bus(variant, ids=ids)
            return found, Discovery(protocol, tuple(report.found), ids)
    raise BusError("commission: a wrist needs exactly three MX-106 servos on its bus; found "
                   + "; ".join(tried))


def commission(profile: Profile, port: str, imu: ImuSource | None, jig: bool,
               on_stage: Callable[[str], None],
               stop: EstopRelay | None = None,
               on_nudge: Callable[[NudgeResult], None] | None = None,
               ask: Ask | None = None) -> Commissioned:
    """Discover, (jig), map and zero the wrist on ``port``; the commissioned profile.
    ``stop``: the run's E-stop, attached to each motion process in turn (once pressed, the
    nudging ends with the wrist holding where it stopped, as it does at any end once the map
    stage began: the operator lifts the jig then);
    ``on_nudge``: each nudge's
    outcome, as it comes (the run log). Without an IMU the operator says which leg each
    nudge moved, and which way (``ask``)."""
    if imu is None and ask is None:
        raise BadInputError("commission: without an IMU the operator must be asked which leg "
                            "each nudge moved")
    found_profile, disc = discover(profile, port, on_stage, stop)
    session = Session(found_profile, port=port, sim=False)
    try:
        session.connect(check=False)
        client = session.require_bus()
        if stop is not None:
            stop.attach(client)
        jig_by_id: dict[int, float] | None = None
        held_at_jig: tuple[int, ...] = ()
        if jig:
            held_at_jig = tuple(j.id for j in client.query(BusQuery("joints")).joints
                                if j.torque)
            if held_at_jig:
                on_stage(f"jig: warning: servo ids {list(held_at_jig)} held the wrist (torque "
                         "on); a wrist on its jig is powered with torque off")
            on_stage("jig: torque off, averaging each servo's ticks at the home jig")
            client.query(BusQuery("torque", on=False))
            jig_by_id = _jig_ticks(client, disc.ids)
        home = np.asarray(profile.home.theta_deg, float)
        axes = leg_axes(model_of(profile), np.radians(home))
        elbows = elbow_motions(model_of(profile), home)
        matches: list[LegMatch] = []
        nudges: list[NudgeResult] = []
        swings: list[Swing] = []
        map_begun = [False]  # the operator lifts the jig at the map stage's first line

        def nudge(ident: int, offset: float) -> NudgeResult:
            if stop is not None:  # a stop that came as the last nudge ended starts no other
                stop.check()
            r = client.nudge(((ident, offset),), MAP_SPEED_DEGPS)
            nudges.append(r)
            if on_nudge is not None:
                on_nudge(r)
            if not r.ok:
                where = ("the servos went back to where they rested and hold there at full "
                         "effort" if r.returned else "the servos hold where they are")
                raise BusError(f"commission: the nudge of servo id {ident} stopped "
                               f"({r.stopped}); the farthest a servo went from its rest: "
                               f"{r.max_away_deg:.2f}°; {where}. Check the wrist moves freely")
            return r

        try:
            for ident in disc.ids:
                map_begun[0] = True
                on_stage(f"map: nudging servo id {ident} by {MAP_NUDGE_DEG:g}°")
                if imu is None:
                    assert ask is not None
                    matches.append(_asked(ident, nudge, ask, elbows))
                    continue
                q0 = _mean_quaternion(imu)
                nudge(ident, MAP_NUDGE_DEG)
                q1 = _mean_quaternion(imu)
                nudge(ident, 0.0)
                try:
                    matches.append(match_leg(axes, ident, rotation_vector(q0, q1), MAP_NUDGE_DEG))
                except ValueError as exc:
                    raise BusError(f"commission: {exc}") from None
            legs = _distinct_legs(matches, "the IMU" if imu is not None else "the answers")
            _map_line(legs, on_stage)
            if imu is not None and not jig:  # the zero at rest, inside the same ball
                src = imu
                for m in sorted(matches, key=lambda m: m.leg):
                    on_stage(f"zero: swinging leg {m.leg} (id {m.id}) ±{SWING_DEG:g}° about its "
                             "rest")
                    swings.append(swing(m.id, nudge, lambda n: _mean_quaternion(src, n)))
        finally:
            # once the map stage began the wrist holds where it is, whatever ended the stage
            # (the operator lifted the jig at "map": torque off would leave it unsupported);
            # before, it rests as found
            client.end_nudging(hold=map_begun[0] or (stop is not None and bool(stop.reason)))
    finally:
        if stop is not None:
            stop.detach()
        session.close()
    on_stage("map: done; the wrist holds where it is, torque on")
    offsets = None
    jig_ticks = None
    trims = (0.0, 0.0, 0.0)
    rest = None
    if jig_by_id is not None:
        jig_ticks = (jig_by_id[legs[0].id], jig_by_id[legs[1].id], jig_by_id[legs[2].id])
        offsets = zero_from_jig(profile, [m.direction for m in legs], jig_ticks)
    elif swings:
        rest = zero_at_rest(found_profile, legs, swings, rotation_noise_deg())
        offsets, trims = rest.offsets, rest.trims
        on_stage("zero: at rest θ = " + ", ".join(
            f"{t:.2f} ± {e:.2f}" for t, e in zip(rest.fit.theta_deg, rest.fit.theta_std_deg,
                                                 strict=True))
            + f"° (rotations explained to {rest.fit.residual_rms_deg:.4f}° RMS)")
    built = _with_wiring(found_profile, legs, offsets, trims)
    tpd = profile.bus.ticks_per_turn / 360.0
    farthest = max((abs(b - a) / tpd for r in nudges
                    for a, b in zip(r.rest_ticks, r.reached_ticks, strict=True)), default=0.0)
    return Commissioned(disc, (legs[0], legs[1], legs[2]), jig_ticks, offsets, built,
                        nudge_s=sum(r.duration_s for r in nudges), max_nudge_deg=farthest,
                        tick_trims=trims, rest_zero=rest, held_at_jig=held_at_jig)


def _map_line(legs: Sequence[LegMatch], on_stage: Callable[[str], None]) -> None:
    """The map found, one line, as soon as it is known (before a zero at rest's swings)."""
    on_stage("map: " + ", ".join(f"leg {m.leg} = id {m.id} ({'+' if m.direction > 0 else '−'})"
                                 for m in legs))


def _distinct_legs(matches: Sequence[LegMatch], by: str) -> list[LegMatch]:
    """The matches by leg 1..3; BusError when two servos drive one leg (by ``by``)."""
    legs = sorted(matches, key=lambda m: m.leg)
    if [m.leg for m in legs] != [1, 2, 3]:
        raise BusError(f"commission: two servos drive the same leg by {by} ("
                       + ", ".join(f"id {m.id} → leg {m.leg}" for m in matches)
                       + "): repeat with the wrist free to move")
    return legs


#: How the operator is asked (question, allowed answers) -> the answer given.
Ask = Callable[[str, Sequence[str]], str]
#: Answers the operator may give to see the nudge again.
AGAIN = "again"
#: Seconds the operator has to answer one question (the nudged servo holds meanwhile).
ANSWER_TIMEOUT_S = 600.0


def _asked(ident: int, nudge: Callable[[int, float], object], ask: Ask,
           elbows: Sequence[ElbowMotion]) -> LegMatch:
    """Nudge ``ident`` out, ask which leg's elbow moved and which way, bring it back (as often
    as the operator asks to see it again)."""
    while True:
        nudge(ident, MAP_NUDGE_DEG)
        try:
            leg = ask(f"servo id {ident} turned {MAP_NUDGE_DEG:g}°: which leg's arm moved?",
                      ("1", "2", "3", AGAIN))
            seen = AGAIN
            if leg != AGAIN:
                motion = elbows[int(leg) - 1]
                seen = ask(f"which way did leg {leg}'s elbow move: {motion.question}?",
                           (*motion.answers, AGAIN))
        finally:
            nudge(ident, 0.0)
        if seen != AGAIN:
            # it was seen going out: the answers describe the +nudge
            return operator_match(ident, int(leg), seen, motion, MAP_NUDGE_DEG)


def refined(result: Commissioned, refinement: Refinement,
            payload_kg: float | None = None) -> Commissioned:
    """``result`` with each tick offset moved by the horn offset the IMU stage found beyond
    the jig's zero (true θ = θ read + δ, so the zero moves by −d·δ ticks): the nearest whole
    tick, and the rest as the joint's ``tick_trim``; the link arcs, the base's tilt and the
    load model (the payload's first moment, the drive's compliance) where the stage
    determined them; with the
    payload's weighed mass ``payload_kg`` (kg), that mass where the first moment was written."""
    if result.tick_offsets is None:
        raise BadInputError("commission: the IMU stage refines a zero (the jig's, or the IMU's at "
                            "rest); there is none")
    tpt = result.profile.bus.ticks_per_turn
    # from the zero the stage ran on: the whole tick and its trim (a zero at rest has one)
    zeros = [off + trim - m.direction * d * tpt / 360.0 for off, trim, m, d in
             zip(result.tick_offsets, result.tick_trims, result.legs, refinement.horn_deg,
                 strict=True)]
    new, trims = ticks_and_trims(zeros, tpt)
    profile = _with_wiring(result.profile, result.legs, new, trims)
    if refinement.arcs_deg is not None:
        profile = with_arcs(profile, *refinement.arcs_deg)
    if refinement.tilt_deg is not None:
        profile = with_tilt(profile, refinement.tilt_deg)
    if refinement.payload is not None:
        profile = validated(with_load_model(profile, refinement.payload, payload_kg))
    return replace(result, tick_offsets=new, tick_trims=trims, refinement=refinement,
                   profile=profile,
                   payload_kg_weighed=payload_kg or result.profile.plant.payload_kg)


def _jig_ticks(client: MotionClient, ids: Sequence[int]) -> dict[int, float]:
    """Each servo's ticks averaged over :data:`JIG_READS` reads (a lost reply is read again,
    up to :data:`JIG_READS` times in all)."""
    sums = dict.fromkeys(ids, 0.0)
    done = lost = 0
    while done < JIG_READS:
        try:
            joints = client.query(BusQuery("joints")).joints
        except BusError:
            lost += 1
            if lost >= JIG_READS:
                raise
            continue
        for j in joints:
            sums[j.id] += j.ticks
        done += 1
    return {i: v / JIG_READS for i, v in sums.items()}


def zero_from_jig(profile: Profile, directions: Sequence[int],
                  jig_ticks: Sequence[float]) -> tuple[int, int, int]:
    """Tick offsets that read the profile's home at the jig: tick_offset = ticks − d·θ_home
    in ticks, modulo one turn, rounded to a tick."""
    tpt = profile.bus.ticks_per_turn
    out = []
    for d, ticks, home in zip(directions, jig_ticks, profile.home.theta_deg, strict=True):
        out.append(round(ticks - d * home * tpt / 360.0) % tpt)
    return (out[0], out[1], out[2])


def _mean_quaternion(imu: ImuSource, n: int = IMU_SAMPLES) -> F:
    qs = np.array([imu.quaternion() for _ in range(n)], float)
    qs *= np.where(qs @ qs[0] < 0, -1.0, 1.0)[:, None]  # one hemisphere
    q = qs.mean(axis=0)
    norm = float(np.linalg.norm(q))
    if not math.isfinite(norm) or norm < 0.5:
        raise BusError("commission: the IMU's quaternion is not a rotation (is it fused, "
                       "IMU mode?)")
    return np.asarray(q / norm, float)


def _scan(profile: Profile, port: str, stop: EstopRelay | None = None) -> BusReport:
    """Every id 0..252 pinged once, by a motion process on ``profile``'s protocol."""
    if stop is not None:
        stop.check()
    session = Session(profile, port=port, sim=False)
    try:
        session.connect(check=False)
        report = session.require_bus().query(BusQuery("scan"))
        assert isinstance(report, BusReport)
        return report
    finally:
        session.close()


def _with_bus(profile: Profile, protocol: str | None = None, model_number: int | None = None,
              ids: Sequence[int] | None = None) -> Profile:
    changes: dict[str, object] = {}
    if protocol is not None:
        changes["protocol"] = protocol
    if model_number is not None:
        changes["model_number"] = model_number
    bus = profile.bus.model_copy(update=changes)
    if ids is not None:
        joints = tuple(j.model_copy(update={"id": i}) for j, i in zip(bus.joints, ids, strict=True))
        bus = bus.model_copy(update={"joints": joints})
    return validated(profile.model_copy(update={"bus": bus}))


def _with_wiring(profile: Profile, legs: Sequence[LegMatch], offsets: Sequence[int] | None,
                 trims: Sequence[float] = (0.0, 0.0, 0.0)) -> Profile:
    joints = []
    for k, (j, m) in enumerate(zip(profile.bus.joints, legs, strict=True)):
        update: dict[str, object] = {"id": m.id, "direction": m.direction}
        if offsets is not None:
            update["tick_offset"] = offsets[k]
            update["tick_trim"] = float(trims[k])
        joints.append(j.model_copy(update=update))
    bus = profile.bus.model_copy(update={"joints": tuple(joints)})
    return validated(profile.model_copy(update={"bus": bus}))
