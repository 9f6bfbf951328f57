"""The run log of a commissioning, like any run's: a folder under the log root with
``meta.json`` (kind ``commission``, the bus and IMU ports, the jig), ``events.jsonl`` (every
stage line, every nudge with its rest, goal and reached ticks, the map, the zero, the fit,
the profile written, the outcome), ``imu.csv`` (every IMU reading taken,
:mod:`spm_console.motion.logs.imu_log`) and ``run.mcap`` with an ``/imu`` topic
(sensor_msgs/msg/Imu) beside ``/spm/events``. ``samples.csv`` has the header only: the
commissioning's planned moves are runs of their own, named in its events.

Closed however the commissioning ends: ``completed``, ``stopped`` (an E-stop: a key, a
signal), ``refused`` (an operator error, a stage that failed), ``error`` (a bug)."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from spm_console.config.schema import Profile
from spm_console.devices.imu.bno055 import ImuSample
from spm_console.motion.logs.imu_log import ImuCsv
from spm_console.motion.logs.mcap_log import mcap_beside
from spm_console.motion.logs.profile_record import wrist_digests
from spm_console.motion.logs.run_end import run_end
from spm_console.motion.logs.runlog import RunLog
from spm_console.motion.nudge import NudgeResult


class CommissionLog:
    """One commissioning's run folder (create with :meth:`create`; end with :meth:`finish`
    or :meth:`failed`)."""

    def __init__(self, run: RunLog) -> None:
        self.run = run
        self.t0 = time.monotonic()
        self.imu_rows = ImuCsv(run.path, self.t0)

    @classmethod
    def create(cls, profile: Profile, root: str | Path | None, **commission: object) -> CommissionLog:
        """``commission``: what the operator asked (ports, jig, IMU stage), in ``meta.json``."""
        run = RunLog.create("commission", profile.name, profile.digest(), [], root=root,
                            extra={"commission": commission}, wrist=wrist_digests(profile))
        run.on_finish = mcap_beside(profile)
        return cls(run)

    @property
    def path(self) -> Path:
        return self.run.path

    def _t(self) -> float:
        return time.monotonic() - self.t0

    def event(self, name: str, **data: object) -> None:
        if not self.run.finished:
            self.run.event(name, self._t(), **data)

    def staged(self, on_stage: Callable[[str], None]) -> Callable[[str], None]:
        """``on_stage``, each line logged first (event ``stage``)."""

        def both(line: str) -> None:
            self.event("stage", message=line)
            on_stage(line)

        return both

    def asking(self, ask: Callable[[str, Sequence[str]], str]) -> Callable[[str, Sequence[str]], str]:
        """``ask``, each question and its answer logged (event ``asked``)."""

        def logged(question: str, answers: Sequence[str]) -> str:
            answer = ask(question, answers)
            self.event("asked", question=question, answers=list(answers), answer=answer)
            return answer

        return logged

    def nudge(self, r: NudgeResult) -> None:
        self.event("nudge", ids=list(r.ids), rest_ticks=list(r.rest_ticks),
                   goal_ticks=list(r.goal_ticks), reached_ticks=list(r.reached_ticks),
                   max_lag_deg=r.max_lag_deg, duration_s=r.duration_s, stopped=r.stopped,
                   max_away_deg=r.max_away_deg, returned=r.returned)

    def imu(self, sample: ImuSample) -> None:
        if not self.run.finished:
            self.imu_rows.add(sample)

    def finish(self, outcome: str, exit_code: int, message: str,
               stats: Mapping[str, object] | None = None) -> None:
        if self.run.finished:
            return
        self.event(outcome, message=message, exit_code=exit_code)
        self.imu_rows.close()
        self.run.finish(outcome, exit_code, message, {"imu_rows": self.imu_rows.rows,
                                                      **(stats or {})})

    def failed(self, exc: BaseException) -> None:
        """Close the log for ``exc`` (:func:`~spm_console.motion.logs.run_end.run_end`)."""
        end = run_end(exc)
        self.finish(end.outcome, end.exit_code, end.message)
