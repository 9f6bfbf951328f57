"""One commissioning as the CLI and the console run it: the IMU opened, the stages in order
(:func:`~.stages.commission`, then the IMU stage on the zero found), the profile
written, everything in the commissioning's run log (:mod:`.log`), closed however it ends.

A stop (the E-stop of :class:`~spm_console.services.client.EstopRelay`: a key, a signal)
ends it with the wrist holding where it stopped: exit 20 once anything moved (an E-stop), 130
before (an interruption); nothing is written."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from spm_console.config.schema import Profile
from spm_console.errors import EStopError, InterruptedBySignalError, SpmError
from spm_console.motion.nudge import NudgeResult
from spm_console.services.client import EstopRelay
from spm_console.services.commissioning.imu_stage import refine_with_imu
from spm_console.services.commissioning.log import CommissionLog
from spm_console.services.commissioning.profile_out import write_commissioned
from spm_console.services.commissioning.stages import (
    Ask,
    Bno055Source,
    Commissioned,
    commission,
    refined,
)


@dataclass(frozen=True)
class CommissionRequest:
    """What the operator asked for."""

    port: str
    """The servo bus."""
    imu_port: str | None
    """The BNO055 on the platform (UART); None: the operator says which leg each nudge moved
    (the IMU stage needs the IMU)."""
    jig: bool
    """The wrist rests on its home jig, torque off: zero the servos there."""
    imu_stage: bool = True
    """After the zero (the jig's, or the IMU's at rest), the IMU stage (poses, fit,
    verification)."""
    out: Path | None = None
    """Where to write the profile (None: beside the profile, never over a file)."""
    logs_root: str | Path | None = None
    """The run logs' root (None: ``$SPM_CONSOLE_LOGS`` or ``logs/``)."""
    payload_kg: float | None = None
    """The payload's mass as weighed, kg: with the first moment the IMU stage fits, it is
    written (``[plant] payload_kg``) and places the payload (None: not known)."""


def _same_device(a: str, b: str) -> bool:
    """Whether two port names open one device (a symbolic link, /dev/serial/by-id/…, names
    the device it points at)."""
    if a.startswith("unix:") or b.startswith("unix:"):
        return a == b
    return os.path.realpath(a) == os.path.realpath(b)


def options_problem(port: str, imu_port: str | None, jig: bool, imu_stage: bool,
                    payload_kg: float | None) -> str:
    """Why these options do not go together ("" when they do): the rules the CLI (a usage
    error) and the console's form (the reason under its fields) both apply, before anything
    is opened."""
    if imu_port and _same_device(port, imu_port):
        return f"the servo bus and the IMU need ports of their own (both name {port})"
    if not jig and not imu_port:
        return ("nothing would zero the wrist: give the home jig (the wrist on it, torque off) "
                "or the IMU's port (it zeroes the wrist where it rests)")
    if payload_kg is not None and not (imu_stage and imu_port):
        return "the payload's mass needs the IMU stage (the IMU's port): it fits where the payload sits"
    return ""


@dataclass(frozen=True)
class CommissionOutcome:
    result: Commissioned
    written: Path
    """The commissioned profile."""
    log_dir: Path
    """The commissioning's run folder."""


def run_commissioning(profile: Profile, profile_path: Path, req: CommissionRequest,
                      on_stage: Callable[[str], None], stop: EstopRelay,
                      ask: Ask | None = None) -> CommissionOutcome:
    """Commission the wrist on ``req.port`` (see the module docstring); ``profile_path``: the
    profile's file, whose text the commissioned profile keeps; ``ask``: the operator, asked
    which leg each nudge moved when there is no IMU (each question and answer is logged)."""
    with_imu_stage = req.imu_stage and req.imu_port is not None
    log = CommissionLog.create(profile, req.logs_root, port=req.port, imu_port=req.imu_port,
                               jig=req.jig, imu_stage=with_imu_stage)
    asked = None if ask is None else log.asking(ask)
    staged = log.staged(on_stage)
    moved = [False]

    def nudged(r: NudgeResult) -> None:
        moved[0] = True
        log.nudge(r)

    try:
        imu = None if req.imu_port is None else Bno055Source(req.imu_port, on_sample=log.imu)
        try:
            result = commission(profile, req.port, imu, req.jig, staged, stop, nudged, asked)
            if with_imu_stage and imu is not None:
                prior = (None if result.rest_zero is None
                         else result.rest_zero.fit.theta_std_deg)
                result = refined(result, refine_with_imu(result.profile, req.port, imu,
                                                         staged, stop, req.logs_root, prior),
                                 req.payload_kg)
        finally:
            if imu is not None:
                imu.close()
        stop.check()
        written = write_commissioned(profile_path, result, req.out, run=log.path.name,
                                     port=req.port)
    except BaseException as exc:
        raised = _stopped(exc, stop, moved[0])
        log.failed(raised)
        if raised is not exc:
            raise raised from None
        raise
    log.event("commissioned", profile_written=str(written),
              legs=[{"leg": m.leg, "id": m.id, "direction": m.direction} for m in result.legs],
              tick_offsets=result.tick_offsets, jig_ticks=result.jig_ticks,
              imu_stage=result.refinement is not None)
    log.finish("completed", 0, f"profile written: {written}")
    return CommissionOutcome(result, written, log.path)


def _stopped(exc: BaseException, stop: EstopRelay, moved: bool) -> BaseException:
    """What a stop made of ``exc``: the E-stop's error (20) once anything moved, an
    interruption (130) before; ``exc`` itself when nothing was pressed."""
    if not stop.reason or not isinstance(exc, SpmError):
        return exc
    if moved:
        return EStopError(f"commission stopped: E-stop: {stop.reason}; the wrist holds where it "
                          "stopped (its PWM Limits restored). Nothing was written")
    return InterruptedBySignalError(f"commission interrupted: {stop.reason}; nothing moved and "
                                    "nothing was written")
